//! The recorder's thread: turns queued frames and events into log operations (eq. 5's
//! ellipses, eq. 6's touchdowns, eq. 7's swing paths, forces in their cones, the robot's pose)
//! and hands them to the backend.

use crate::backend::Backend;
use crate::frame::{Frame, Message, PushEvent, Touchdown};
use crate::ops::{rgb, Op, Ops, Rgba};
use crate::scene::{self, GHOST, ROBOT};
use crate::{RunView, VizError};
use eemp_core::body_state::RobotState;
use eemp_core::leg::Leg;
use eemp_sim::backend::Simulation;
use nalgebra::{Rotation3, Vector3};
use std::sync::mpsc::{Receiver, Sender};

pub use crate::ops::TIMELINE;

/// Force arrows: metres drawn per newton (a 12.5 kg A1 standing on four feet: ~3 cm each).
const FORCE_M_PER_N: f64 = 0.001;
/// Points on a drawn ellipse or swing path.
const ELLIPSE_POINTS: usize = 48;
const SWING_POINTS: usize = 24;

const INSIDE: Rgba = rgb(60, 180, 90);
const OUTSIDE: Rgba = rgb(220, 60, 50);
const PLANNED: Rgba = rgb(255, 165, 0);
const ACTUAL: Rgba = rgb(40, 90, 230);
const FORCE: Rgba = rgb(200, 40, 200);
const CONE: Rgba = [200, 40, 200, 110];
const PUSH: Rgba = rgb(230, 30, 30);
const CENTRE: Rgba = rgb(120, 120, 120);

/// What the thread reports when its queue is closed.
pub struct WriterReport {
    pub log_errors: usize,
    pub flushed: bool,
}

pub struct Writer {
    backend: Box<dyn Backend>,
    /// A model of the same robot, posed (not simulated) at each frame's state.
    poser: Simulation,
    bodies: Vec<(usize, String)>,
    log_errors: usize,
}

fn p32(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

impl Writer {
    /// Logs the static scene (the robot's and terrain's geoms, the series' names) now.
    pub fn new(mut backend: Box<dyn Backend>, run: &RunView) -> Result<Self, VizError> {
        let poser = Simulation::new(&run.robot, &run.scene)
            .map_err(|e| VizError::Target(format!("cannot build the robot's model: {e}")))?;
        let model = poser.model();
        let mut ops = Ops::default();
        scene::static_scene(&mut ops, &model, run.estimated);
        crate::layout::series_styles(&mut ops, run.estimated);
        let errors = backend.log(&ops.0);
        if errors > 0 {
            return Err(VizError::Target(format!(
                "cannot log the scene: {errors} log calls failed"
            )));
        }
        Ok(Writer {
            bodies: scene::robot_bodies(&model),
            backend,
            poser,
            log_errors: 0,
        })
    }

    /// Logs until the queue closes, then flushes and reports on `done`.
    pub fn run(mut self, rx: Receiver<Message>, done: Sender<WriterReport>) {
        for message in rx {
            let mut ops = Ops::default();
            match message {
                Message::Frame(f) => self.frame(&mut ops, &f),
                Message::Touchdown(td) => touchdown(&mut ops, &td),
                Message::Push(p) => push(&mut ops, &p),
            }
            self.log_errors += self.backend.log(&ops.0);
        }
        let (flushed, failed) = self.backend.finish();
        self.log_errors += failed;
        let _ = done.send(WriterReport {
            log_errors: self.log_errors,
            flushed,
        });
    }

    fn pose(&mut self, ops: &mut Ops, root: &str, state: &RobotState) {
        self.poser.set_pose(state);
        let data = self.poser.data();
        for (b, name) in &self.bodies {
            let p = data.xpos()[*b];
            let q = data.xquat()[*b];
            ops.push(Op::Transform {
                path: format!("{root}/{name}"),
                translation: [p[0] as f32, p[1] as f32, p[2] as f32],
                quaternion_wxyz: [q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32],
                is_static: false,
            });
        }
    }

    fn frame(&mut self, ops: &mut Ops, f: &Frame) {
        ops.time(f.time_s);
        self.pose(ops, ROBOT, &f.truth);
        if let Some(est) = &f.estimate {
            self.pose(ops, GHOST, est);
        }
        plan(ops, f);
        forces(ops, f);
        plots(ops, f);
    }
}

/// Eq. (5)'s ellipses (green: foot inside, red: outside), the running swings' eq. (7) paths
/// and their eq. (6) touchdown points.
fn plan(ops: &mut Ops, f: &Frame) {
    let Some(g) = &f.geometry else {
        return;
    };
    let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), g.heading_yaw_rad);
    let strips: Vec<Vec<[f32; 3]>> = Leg::ALL
        .iter()
        .map(|leg| {
            let c = g.ellipse_centres_world[*leg];
            (0..=ELLIPSE_POINTS)
                .map(|k| {
                    let a = k as f64 / ELLIPSE_POINTS as f64 * std::f64::consts::TAU;
                    let d = heading
                        * Vector3::new(g.ellipse_rx_m * a.cos(), g.ellipse_ry_m * a.sin(), 0.0);
                    p32(&(c + d))
                })
                .collect()
        })
        .collect();
    let colours = Leg::ALL
        .iter()
        .map(|leg| {
            if g.ellipse_values[*leg] > 1.0 {
                OUTSIDE
            } else {
                INSIDE
            }
        })
        .collect();
    ops.push(Op::Strips {
        path: "world/plan/ellipses".into(),
        strips,
        colours,
        radius: 0.003,
        labels: Leg::ALL
            .iter()
            .map(|l| l.short_name().to_string())
            .collect(),
    });
    ops.push(Op::Points {
        path: "world/plan/ellipse_centres".into(),
        points: Leg::ALL
            .iter()
            .map(|l| p32(&g.ellipse_centres_world[*l]))
            .collect(),
        colours: vec![CENTRE],
        radius: 0.006,
    });
    let swinging: Vec<_> = Leg::ALL.iter().filter_map(|l| g.swings[*l]).collect();
    ops.push(Op::Strips {
        path: "world/plan/swing_paths".into(),
        strips: swinging
            .iter()
            .map(|s| {
                (0..=SWING_POINTS)
                    .map(|k| {
                        let tau = k as f64 / SWING_POINTS as f64 * s.trajectory.duration_s;
                        p32(&s.trajectory.sample(tau).p_body)
                    })
                    .collect()
            })
            .collect(),
        colours: vec![PLANNED],
        radius: 0.002,
        labels: Vec::new(),
    });
    ops.push(Op::Points {
        path: "world/plan/touchdowns".into(),
        points: swinging.iter().map(|s| p32(&s.touchdown_world)).collect(),
        colours: vec![PLANNED],
        radius: 0.012,
    });
}

/// Stance forces as arrows from the feet, each inside its friction cone (the MPC's μ).
fn forces(ops: &mut Ops, f: &Frame) {
    let legs: Vec<Leg> = Leg::ALL
        .into_iter()
        .filter(|l| f.forces_world[*l].norm() > 1.0)
        .collect();
    ops.push(Op::Arrows {
        path: "world/forces".into(),
        origins: legs.iter().map(|l| p32(&f.feet_world[*l])).collect(),
        vectors: legs
            .iter()
            .map(|l| p32(&(f.forces_world[*l] * FORCE_M_PER_N)))
            .collect(),
        colour: FORCE,
        radius: 0.004,
    });
    let mut cones = Vec::new();
    if let Some(mu) = f.mpc.map(|m| m.friction_coefficient) {
        for l in &legs {
            let height = (f.forces_world[*l].z * FORCE_M_PER_N).max(0.0);
            let foot = f.feet_world[*l];
            let rim: Vec<Vector3<f64>> = (0..=16)
                .map(|k| {
                    let a = k as f64 / 16.0 * std::f64::consts::TAU;
                    foot + Vector3::new(mu * height * a.cos(), mu * height * a.sin(), height)
                })
                .collect();
            cones.push(rim.iter().map(p32).collect::<Vec<_>>());
            for p in rim.iter().step_by(4) {
                cones.push(vec![p32(&foot), p32(p)]);
            }
        }
    }
    ops.push(Op::Strips {
        path: "world/forces/friction_cones".into(),
        strips: cones,
        colours: vec![CONE],
        radius: 0.001,
        labels: Vec::new(),
    });
}

fn plots(ops: &mut Ops, f: &Frame) {
    let v = f.truth.body.v_heading();
    let c = f.command;
    ops.scalar("plots/velocity/vx/commanded", c.vx_mps);
    ops.scalar("plots/velocity/vx/actual", v.x);
    ops.scalar("plots/velocity/vy/commanded", c.vy_mps);
    ops.scalar("plots/velocity/vy/actual", v.y);
    ops.scalar("plots/velocity/yaw_rate/commanded", c.yaw_rate_rps);
    ops.scalar("plots/velocity/yaw_rate/actual", f.truth.body.omega_world.z);
    if let Some(est) = &f.estimate {
        ops.scalar(crate::layout::ESTIMATED_VX, est.body.v_heading().x);
    }
    if let Some(cot) = f.cot_so_far {
        ops.scalar("plots/efficiency/cot", cot);
    }
    if let Some(m) = f.manipulability_so_far {
        ops.scalar("plots/efficiency/manipulability", m);
    }
    for leg in Leg::ALL {
        for (j, joint) in ["hip", "thigh", "calf"].iter().enumerate() {
            ops.scalar(
                format!("plots/torque/{}/{joint}", leg.short_name()),
                f.torques_nm[leg][j],
            );
        }
        if let Some(g) = &f.geometry {
            ops.scalar(
                format!("plots/ellipse/{}", leg.short_name()),
                g.ellipse_values[leg],
            );
        }
        ops.scalar(
            format!("plots/contact/{}", leg.short_name()),
            f.loaded[leg] as u8 as f64,
        );
    }
    if let Some(m) = f.mpc {
        ops.scalar("plots/mpc/solve_time_ms", m.solve_time_s * 1e3);
        ops.scalar("plots/mpc/friction_mu", m.friction_coefficient);
    }
}

/// Where a foot landed against where eq. (6) put it, and the distance between them.
fn touchdown(ops: &mut Ops, td: &Touchdown) {
    ops.time(td.time_s);
    let n = td.leg.short_name();
    ops.push(Op::Points {
        path: format!("world/touchdowns/actual/{n}"),
        points: vec![p32(&td.p_foot_world)],
        colours: vec![ACTUAL],
        radius: 0.012,
    });
    if let Some(planned) = td.planned_world {
        ops.push(Op::Points {
            path: format!("world/touchdowns/planned/{n}"),
            points: vec![p32(&planned)],
            colours: vec![PLANNED],
            radius: 0.009,
        });
        let miss = (td.p_foot_world.xy() - planned.xy()).norm();
        ops.scalar(format!("plots/touchdown_error_m/{n}"), miss);
    }
}

fn push(ops: &mut Ops, p: &PushEvent) {
    ops.time(p.time_s);
    // 0.5 m drawn per m/s of velocity change.
    ops.push(Op::Arrows {
        path: "world/pushes".into(),
        origins: vec![p32(&p.p_trunk_world)],
        vectors: vec![p32(&(p.dv_world * 0.5))],
        colour: PUSH,
        radius: 0.01,
    });
}
