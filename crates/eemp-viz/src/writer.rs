//! The recorder's thread: turns queued frames and events into Rerun log calls.

use crate::frame::{Frame, Message, PushEvent, Touchdown};
use crate::scene::{self, GHOST, ROBOT};
use crate::{RunView, VizError};
use eemp_core::body_state::RobotState;
use eemp_core::leg::Leg;
use eemp_sim::backend::Simulation;
use nalgebra::{Rotation3, Vector3};
use rerun::datatypes::Rgba32;
use rerun::RecordingStream;
use std::sync::mpsc::{Receiver, Sender};
use std::time::Duration;

/// The simulation-time timeline every entity is logged on.
pub const TIMELINE: &str = "sim_time";

/// Force arrows: metres drawn per newton (a 12.5 kg A1 standing on four feet: ~3 cm each).
const FORCE_M_PER_N: f64 = 0.001;
/// Points on a drawn ellipse or swing path.
const ELLIPSE_POINTS: usize = 48;
const SWING_POINTS: usize = 24;

const INSIDE: Rgba32 = Rgba32::from_rgb(60, 180, 90);
const OUTSIDE: Rgba32 = Rgba32::from_rgb(220, 60, 50);
const PLANNED: Rgba32 = Rgba32::from_rgb(255, 165, 0);
const ACTUAL: Rgba32 = Rgba32::from_rgb(40, 90, 230);
const FORCE: Rgba32 = Rgba32::from_rgb(200, 40, 200);
const CONE: Rgba32 = Rgba32::from_unmultiplied_rgba(200, 40, 200, 110);
const PUSH: Rgba32 = Rgba32::from_rgb(230, 30, 30);

/// What the thread reports when its queue is closed.
pub struct WriterReport {
    pub log_errors: usize,
    pub flushed: bool,
}

pub struct Writer {
    rec: RecordingStream,
    /// A model of the same robot, posed (not simulated) at each frame's state.
    poser: Simulation,
    bodies: Vec<(usize, String)>,
    flush_on_drop: bool,
    log_errors: usize,
}

fn p32(v: &Vector3<f64>) -> [f32; 3] {
    [v.x as f32, v.y as f32, v.z as f32]
}

impl Writer {
    pub fn new(rec: RecordingStream, run: &RunView, flush_on_drop: bool) -> Result<Self, VizError> {
        let poser = Simulation::new(&run.robot, &run.scene)
            .map_err(|e| VizError::Target(format!("cannot build the robot's model: {e}")))?;
        let model = poser.model();
        let log = |r: rerun::RecordingStreamResult<()>| {
            r.map_err(|e| VizError::Target(format!("cannot log the scene: {e}")))
        };
        log(rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP()))?;
        log(scene::log_static_scene(&rec, &model, run.estimated))?;
        log(crate::blueprint::log_series_styles(&rec, run.estimated))?;
        Ok(Writer {
            bodies: scene::robot_bodies(&model),
            rec,
            poser,
            flush_on_drop,
            log_errors: 0,
        })
    }

    /// Logs until the queue closes, then flushes and reports on `done`.
    pub fn run(mut self, rx: Receiver<Message>, done: Sender<WriterReport>) {
        for message in rx {
            let result = match message {
                Message::Frame(f) => self.frame(&f),
                Message::Touchdown(td) => self.touchdown(&td),
                Message::Push(p) => self.push(&p),
            };
            if result.is_err() {
                self.log_errors += 1;
            }
        }
        let flushed = if self.flush_on_drop {
            // A file is complete only when its writer has finished: wait for it.
            let ok = self.rec.flush_blocking().is_ok();
            drop(self.rec);
            ok
        } else {
            self.rec.flush_with_timeout(Duration::from_secs(5)).is_ok()
        };
        let _ = done.send(WriterReport {
            log_errors: self.log_errors,
            flushed,
        });
    }

    fn pose(&mut self, root: &str, state: &RobotState) -> rerun::RecordingStreamResult<()> {
        self.poser.set_pose(state);
        let data = self.poser.data();
        for (b, name) in &self.bodies {
            let p = data.xpos()[*b];
            let q = data.xquat()[*b];
            self.rec.log(
                format!("{root}/{name}").as_str(),
                &rerun::Transform3D::from_translation([p[0] as f32, p[1] as f32, p[2] as f32])
                    .with_quaternion(rerun::Quaternion::from_wxyz([
                        q[0] as f32,
                        q[1] as f32,
                        q[2] as f32,
                        q[3] as f32,
                    ])),
            )?;
        }
        Ok(())
    }

    fn scalar(&self, path: &str, value: f64) -> rerun::RecordingStreamResult<()> {
        if value.is_finite() {
            self.rec.log(path, &rerun::Scalars::single(value))
        } else {
            Ok(())
        }
    }

    fn frame(&mut self, f: &Frame) -> rerun::RecordingStreamResult<()> {
        self.rec.set_duration_secs(TIMELINE, f.time_s);
        self.pose(ROBOT, &f.truth)?;
        if let Some(est) = &f.estimate {
            self.pose(GHOST, est)?;
        }
        self.plan(f)?;
        self.forces(f)?;
        self.plots(f)
    }

    /// Eq. (5)'s ellipses (green: foot inside, red: outside), the running swings' eq. (7)
    /// paths and their eq. (6) touchdown points.
    fn plan(&mut self, f: &Frame) -> rerun::RecordingStreamResult<()> {
        let Some(g) = &f.geometry else {
            return Ok(());
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
        let colours = Leg::ALL.map(|leg| {
            if g.ellipse_values[leg] > 1.0 {
                OUTSIDE
            } else {
                INSIDE
            }
        });
        self.rec.log(
            "world/plan/ellipses",
            &rerun::LineStrips3D::new(strips)
                .with_colors(colours)
                .with_radii([0.003])
                .with_labels(Leg::ALL.map(|l| l.short_name())),
        )?;
        let centres: Vec<[f32; 3]> = Leg::ALL
            .iter()
            .map(|l| p32(&g.ellipse_centres_world[*l]))
            .collect();
        self.rec.log(
            "world/plan/ellipse_centres",
            &rerun::Points3D::new(centres)
                .with_radii([0.006])
                .with_colors([rerun::Color::from_rgb(120, 120, 120)]),
        )?;
        let swinging: Vec<_> = Leg::ALL.iter().filter_map(|l| g.swings[*l]).collect();
        let paths: Vec<Vec<[f32; 3]>> = swinging
            .iter()
            .map(|s| {
                (0..=SWING_POINTS)
                    .map(|k| {
                        let tau = k as f64 / SWING_POINTS as f64 * s.trajectory.duration_s;
                        p32(&s.trajectory.sample(tau).p_body)
                    })
                    .collect()
            })
            .collect();
        self.rec.log(
            "world/plan/swing_paths",
            &rerun::LineStrips3D::new(paths)
                .with_colors([PLANNED])
                .with_radii([0.002]),
        )?;
        let targets: Vec<[f32; 3]> = swinging.iter().map(|s| p32(&s.touchdown_world)).collect();
        self.rec.log(
            "world/plan/touchdowns",
            &rerun::Points3D::new(targets)
                .with_colors([PLANNED])
                .with_radii([0.012]),
        )
    }

    /// Stance forces as arrows from the feet, each inside its friction cone (the MPC's μ).
    fn forces(&mut self, f: &Frame) -> rerun::RecordingStreamResult<()> {
        let mu = f.mpc.map(|m| m.friction_coefficient);
        let legs: Vec<Leg> = Leg::ALL
            .into_iter()
            .filter(|l| f.forces_world[*l].norm() > 1.0)
            .collect();
        let origins: Vec<[f32; 3]> = legs.iter().map(|l| p32(&f.feet_world[*l])).collect();
        let vectors: Vec<[f32; 3]> = legs
            .iter()
            .map(|l| p32(&(f.forces_world[*l] * FORCE_M_PER_N)))
            .collect();
        self.rec.log(
            "world/forces",
            &rerun::Arrows3D::from_vectors(vectors)
                .with_origins(origins)
                .with_colors([FORCE])
                .with_radii([0.004]),
        )?;
        let mut cones = Vec::new();
        if let Some(mu) = mu {
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
        self.rec.log(
            "world/forces/friction_cones",
            &rerun::LineStrips3D::new(cones)
                .with_colors([CONE])
                .with_radii([0.001]),
        )
    }

    fn plots(&mut self, f: &Frame) -> rerun::RecordingStreamResult<()> {
        let v = f.truth.body.v_heading();
        let c = f.command;
        self.scalar("plots/velocity/vx/commanded", c.vx_mps)?;
        self.scalar("plots/velocity/vx/actual", v.x)?;
        self.scalar("plots/velocity/vy/commanded", c.vy_mps)?;
        self.scalar("plots/velocity/vy/actual", v.y)?;
        self.scalar("plots/velocity/yaw_rate/commanded", c.yaw_rate_rps)?;
        self.scalar("plots/velocity/yaw_rate/actual", f.truth.body.omega_world.z)?;
        if let Some(est) = &f.estimate {
            self.scalar("plots/velocity/vx/estimated", est.body.v_heading().x)?;
        }
        if let Some(cot) = f.cot_so_far {
            self.scalar("plots/efficiency/cot", cot)?;
        }
        if let Some(m) = f.manipulability_so_far {
            self.scalar("plots/efficiency/manipulability", m)?;
        }
        for leg in Leg::ALL {
            for (j, joint) in ["hip", "thigh", "calf"].iter().enumerate() {
                self.scalar(
                    &format!("plots/torque/{}/{joint}", leg.short_name()),
                    f.torques_nm[leg][j],
                )?;
            }
            if let Some(g) = &f.geometry {
                self.scalar(
                    &format!("plots/ellipse/{}", leg.short_name()),
                    g.ellipse_values[leg],
                )?;
            }
            self.scalar(
                &format!("plots/contact/{}", leg.short_name()),
                f.loaded[leg] as u8 as f64,
            )?;
        }
        if let Some(m) = f.mpc {
            self.scalar("plots/mpc/solve_time_ms", m.solve_time_s * 1e3)?;
            self.scalar("plots/mpc/friction_mu", m.friction_coefficient)?;
        }
        Ok(())
    }

    /// Where a foot landed against where eq. (6) put it, and the distance between them.
    fn touchdown(&mut self, td: &Touchdown) -> rerun::RecordingStreamResult<()> {
        self.rec.set_duration_secs(TIMELINE, td.time_s);
        let n = td.leg.short_name();
        self.rec.log(
            format!("world/touchdowns/actual/{n}").as_str(),
            &rerun::Points3D::new([p32(&td.p_foot_world)])
                .with_colors([ACTUAL])
                .with_radii([0.012]),
        )?;
        if let Some(planned) = td.planned_world {
            self.rec.log(
                format!("world/touchdowns/planned/{n}").as_str(),
                &rerun::Points3D::new([p32(&planned)])
                    .with_colors([PLANNED])
                    .with_radii([0.009]),
            )?;
            let miss = (td.p_foot_world.xy() - planned.xy()).norm();
            self.scalar(&format!("plots/touchdown_error_m/{n}"), miss)?;
        }
        Ok(())
    }

    fn push(&mut self, p: &PushEvent) -> rerun::RecordingStreamResult<()> {
        self.rec.set_duration_secs(TIMELINE, p.time_s);
        // 0.5 m drawn per m/s of velocity change.
        self.rec.log(
            "world/pushes",
            &rerun::Arrows3D::from_vectors([p32(&(p.dv_world * 0.5))])
                .with_origins([p32(&p.p_trunk_world)])
                .with_colors([PUSH])
                .with_radii([0.01]),
        )
    }
}
