//! Dog motion capture → A1 reference motion (the original work's retargeting steps, our own
//! code on the core's kinematics; values in `../shared/reference/README.md`):
//!
//! 1. markers rotated +90° about x (y up → z up), then `yaw_rad` about z, scaled by `scale`;
//! 2. root at the pelvis–neck midpoint + `root_offset_m`; heading from pelvis → neck, the
//!    left direction from the shoulders and hips, made horizontal (no roll from the markers);
//! 3. toe targets: the A1's own abduction joint + (dog toe − dog hip/shoulder), the toe's own
//!    height, plus `toe_offset_m` (outward, and up for the hind feet) in the heading frame;
//! 4. the whole motion lifted so that each foot's lowest point averages one foot radius;
//! 5. the loop closed: periodic quantities (root height, roll, pitch, yaw, lateral position and
//!    the toe targets relative to the root) get a linear correction that makes the step from
//!    the last frame to the first like the others (drift of the capture removed), the yaw
//!    turned so that the cycle walks along +x;
//! 6. joint angles by leg inverse kinematics within the joint ranges: the closed form where
//!    the target is reachable, else damped least squares clamped to the ranges; a residual
//!    over `max_residual_m` is an error naming the frame and the toe marker.

use super::mocap::{MocapClip, MocapError, MARKERS, MOCAP_FRAME_S};
use super::motion::{MotionFrame, ReferenceMotion};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::robot::RobotConfig;
use nalgebra::{Matrix3, Rotation3, UnitQuaternion, Vector3};
use std::path::{Path, PathBuf};

/// Marker ids of the capture (AI4Animation dog skeleton).
#[derive(Clone, Debug, PartialEq)]
pub struct MarkerIds {
    pub pelvis: usize,
    pub neck: usize,
    /// Shoulder or hip marker above each leg.
    pub hip: LegMap<usize>,
    pub toe: LegMap<usize>,
}

impl Default for MarkerIds {
    /// The original config lists hips/shoulders [6, 16, 11, 20] and toes [10, 19, 15, 23] as
    /// left front, left rear, right front, right rear. Checked on the data: markers 6, 16, 10
    /// and 19 are on the dog's left (+y once the dog faces +x; test `marker_sides`).
    fn default() -> Self {
        MarkerIds {
            pelvis: 0,
            neck: 3,
            hip: LegMap([11, 6, 20, 16]),
            toe: LegMap([15, 10, 23, 19]),
        }
    }
}

#[derive(Clone, Debug, PartialEq)]
pub struct RetargetConfig {
    pub markers: MarkerIds,
    /// Yaw applied after the y-up → z-up turn, rad (0.47π in the original).
    pub yaw_rad: f64,
    pub scale: f64,
    pub root_offset_m: Vector3<f64>,
    /// Outward lateral toe offset, m (the original's ±0.05).
    pub toe_outward_m: f64,
    /// Extra height of the hind toe targets, m (the original's 0.01).
    pub hind_toe_up_m: f64,
    /// Largest IK residual accepted, m.
    pub max_residual_m: f64,
}

impl Default for RetargetConfig {
    fn default() -> Self {
        RetargetConfig {
            markers: MarkerIds::default(),
            yaw_rad: 0.47 * std::f64::consts::PI,
            scale: 0.825,
            root_offset_m: Vector3::new(0.0, 0.0, -0.06),
            toe_outward_m: 0.05,
            hind_toe_up_m: 0.01,
            max_residual_m: 0.02,
        }
    }
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum RetargetError {
    #[error(transparent)]
    Mocap(#[from] MocapError),
    #[error("{path}: frame {frame}: the A1's {leg} leg cannot reach toe marker {marker}: {residual_mm:.1} mm short (allowed {allowed_mm:.1} mm)")]
    Unreachable {
        path: PathBuf,
        frame: usize,
        leg: &'static str,
        marker: usize,
        residual_mm: f64,
        allowed_mm: f64,
    },
    #[error("{path}: frame {frame}: markers {a} and {b} coincide, no direction to take from them")]
    Degenerate {
        path: PathBuf,
        frame: usize,
        a: usize,
        b: usize,
    },
    #[error("{path}: frames {start}..{end}: a gait cycle needs at least 4 frames")]
    TooShort {
        path: PathBuf,
        start: usize,
        end: usize,
    },
}

/// The capture's marker positions in the z-up, scaled frame of step 1.
pub fn transform_markers(
    cfg: &RetargetConfig,
    raw: &[Vector3<f64>; MARKERS],
) -> [Vector3<f64>; MARKERS] {
    let r = Rotation3::from_axis_angle(&Vector3::z_axis(), cfg.yaw_rad)
        * Rotation3::from_axis_angle(&Vector3::x_axis(), std::f64::consts::FRAC_PI_2);
    raw.map(|p| r * p * cfg.scale)
}

/// Per-frame quantities before IK.
struct Targets {
    p_root: Vector3<f64>,
    /// Roll, pitch, yaw of the root.
    rpy: Vector3<f64>,
    toe_world: LegMap<Vector3<f64>>,
}

fn unit(
    v: Vector3<f64>,
    path: &Path,
    frame: usize,
    a: usize,
    b: usize,
) -> Result<Vector3<f64>, RetargetError> {
    let n = v.norm();
    if n < 1e-9 || !n.is_finite() {
        return Err(RetargetError::Degenerate {
            path: path.to_path_buf(),
            frame,
            a,
            b,
        });
    }
    Ok(v / n)
}

fn root_and_toes(
    cfg: &RetargetConfig,
    kin: &LegKinematics,
    m: &[Vector3<f64>; MARKERS],
    path: &Path,
    frame: usize,
) -> Result<Targets, RetargetError> {
    let ids = &cfg.markers;
    let (pelvis, neck) = (m[ids.pelvis], m[ids.neck]);
    let fwd = unit(neck - pelvis, path, frame, ids.pelvis, ids.neck)?;
    let d_sh = unit(
        m[ids.hip[Leg::FrontLeft]] - m[ids.hip[Leg::FrontRight]],
        path,
        frame,
        ids.hip[Leg::FrontLeft],
        ids.hip[Leg::FrontRight],
    )?;
    let d_hip = unit(
        m[ids.hip[Leg::RearLeft]] - m[ids.hip[Leg::RearRight]],
        path,
        frame,
        ids.hip[Leg::RearLeft],
        ids.hip[Leg::RearRight],
    )?;
    let left = 0.5 * (d_sh + d_hip);
    let up = unit(fwd.cross(&left), path, frame, ids.pelvis, ids.neck)?;
    let mut left = up.cross(&fwd);
    left.z = 0.0; // the original's "make the base more stable": no roll from the markers
    let left = unit(
        left,
        path,
        frame,
        ids.hip[Leg::FrontLeft],
        ids.hip[Leg::FrontRight],
    )?;
    let up = unit(fwd.cross(&left), path, frame, ids.pelvis, ids.neck)?;
    let fwd = left.cross(&up);
    let r = Rotation3::from_matrix_unchecked(Matrix3::from_columns(&[fwd, left, up]));
    let (roll, pitch, yaw) = r.euler_angles();
    let p_root = 0.5 * (pelvis + neck) + cfg.root_offset_m;
    let heading = Rotation3::from_axis_angle(&Vector3::z_axis(), yaw);
    let toe_world = LegMap::from_fn(|leg| {
        let hip_world = p_root + r * kin.hip_position_body(leg);
        let mut t = hip_world + (m[ids.toe[leg]] - m[ids.hip[leg]]);
        t.z = m[ids.toe[leg]].z;
        let up = if leg.front_sign() < 0.0 {
            cfg.hind_toe_up_m
        } else {
            0.0
        };
        t + heading * Vector3::new(0.0, leg.side_sign() * cfg.toe_outward_m, up)
    });
    Ok(Targets {
        p_root,
        rpy: Vector3::new(roll, pitch, yaw),
        toe_world,
    })
}

/// Makes `x[0..n]` periodic: a linear correction so that x[n-1] + (typical step) = x[0].
fn close_loop(x: &mut [f64]) {
    let n = x.len();
    let step = 0.5 * ((x[1] - x[0]) + (x[n - 1] - x[n - 2]));
    let e = x[0] - (x[n - 1] + step);
    for (k, v) in x.iter_mut().enumerate() {
        *v += e * k as f64 / (n - 1) as f64;
    }
}

/// Leg IK within the joint ranges: closed form when reachable, else damped least squares
/// clamped to the ranges, started from `q_start`. Returns the angles and the residual, m.
pub fn leg_ik(
    kin: &LegKinematics,
    leg: Leg,
    p_foot_body: &Vector3<f64>,
    q_start: &Vector3<f64>,
) -> (Vector3<f64>, f64) {
    if let Ok(q) = kin.inverse(leg, p_foot_body) {
        return (q, (kin.foot_position_body(leg, &q) - p_foot_body).norm());
    }
    let clamp = |q: Vector3<f64>| {
        Vector3::from_fn(|j, _| {
            let [lo, hi] = kin.joint_range(leg, j);
            q[j].clamp(lo, hi)
        })
    };
    let mut q = clamp(*q_start);
    // Damped, step-limited and projected onto the ranges: converges to the closest point the
    // ranges allow instead of oscillating at a clamped joint.
    let lambda2 = 1e-3;
    for _ in 0..500 {
        let e = p_foot_body - kin.foot_position_body(leg, &q);
        if e.norm() < 1e-7 {
            break;
        }
        let mut j = kin.foot_jacobian_body(leg, &q);
        let mut dq = Vector3::zeros();
        // Joints at a limit that the step pushes further out are frozen and the step solved
        // again for the others (a small active set); without it the step stalls there.
        for _ in 0..3 {
            let jt = j.transpose();
            dq = jt
                * (j * jt + Matrix3::identity() * lambda2)
                    .try_inverse()
                    .unwrap_or_else(Matrix3::zeros)
                * e;
            let mut frozen = false;
            for k in 0..3 {
                let [lo, hi] = kin.joint_range(leg, k);
                let pushing_out = (q[k] <= lo && dq[k] < 0.0) || (q[k] >= hi && dq[k] > 0.0);
                if pushing_out && j.column(k).norm() > 0.0 {
                    j.column_mut(k).fill(0.0);
                    frozen = true;
                }
            }
            if !frozen {
                break;
            }
        }
        if dq.norm() > 0.1 {
            dq *= 0.1 / dq.norm();
        }
        q = clamp(q + dq);
    }
    (q, (kin.foot_position_body(leg, &q) - p_foot_body).norm())
}

/// A retargeted cycle with what it was made from, in the cycle frame (for figures).
#[derive(Clone, Debug)]
pub struct Retargeted {
    pub motion: ReferenceMotion,
    /// The toe targets the IK aimed at, per frame (after the loop correction).
    pub toe_targets: Vec<LegMap<Vector3<f64>>>,
    /// The dog's markers, transformed, lifted and in the cycle frame (no loop correction).
    pub dog_markers: Vec<[Vector3<f64>; MARKERS]>,
    /// Largest IK residual over the clip, m.
    pub max_residual_m: f64,
}

/// Retargets frames `start..end` of `clip` to the robot: one loopable gait cycle.
pub fn retarget(
    cfg: &RetargetConfig,
    robot: &RobotConfig,
    clip: &MocapClip,
    start: usize,
    end: usize,
) -> Result<Retargeted, RetargetError> {
    let raw = clip.window(start, end)?;
    if raw.len() < 4 {
        return Err(RetargetError::TooShort {
            path: clip.path.clone(),
            start,
            end,
        });
    }
    let kin = LegKinematics::new(robot);
    let mut t: Vec<Targets> = raw
        .iter()
        .enumerate()
        .map(|(k, m)| root_and_toes(cfg, &kin, &transform_markers(cfg, m), &clip.path, start + k))
        .collect::<Result<_, _>>()?;
    let n = t.len();

    // Step 4: feet on the floor.
    let r_foot = robot.leg.foot_radius_m;
    let mean_low = Leg::ALL
        .iter()
        .map(|&l| {
            t.iter()
                .map(|f| f.toe_world[l].z)
                .fold(f64::INFINITY, f64::min)
        })
        .sum::<f64>()
        / 4.0;
    let lift = r_foot - mean_low;

    // Step 5: express in the cycle frame (start at the origin, walking along +x), close loops.
    let mut yaws: Vec<f64> = t.iter().map(|f| f.rpy.z).collect();
    for k in 1..n {
        while yaws[k] - yaws[k - 1] > std::f64::consts::PI {
            yaws[k] -= 2.0 * std::f64::consts::PI;
        }
        while yaws[k] - yaws[k - 1] < -std::f64::consts::PI {
            yaws[k] += 2.0 * std::f64::consts::PI;
        }
    }
    let travel = t[n - 1].p_root - t[0].p_root;
    let heading = travel.y.atan2(travel.x);
    let to_cycle = Rotation3::from_axis_angle(&Vector3::z_axis(), -heading);
    let origin = Vector3::new(t[0].p_root.x, t[0].p_root.y, 0.0);
    for (k, f) in t.iter_mut().enumerate() {
        f.p_root = to_cycle * (f.p_root - origin);
        f.p_root.z += lift;
        f.rpy.z = yaws[k] - heading;
        for leg in Leg::ALL {
            let mut p = to_cycle * (f.toe_world[leg] - origin);
            p.z += lift;
            f.toe_world[leg] = p;
        }
    }
    let mut series: Vec<Vec<f64>> = Vec::new();
    let get = |f: &Targets| -> Vec<f64> {
        let mut v = vec![f.p_root.y, f.p_root.z, f.rpy.x, f.rpy.y, f.rpy.z];
        for leg in Leg::ALL {
            let rel = f.toe_world[leg] - Vector3::new(f.p_root.x, f.p_root.y, 0.0);
            v.extend(rel.iter());
        }
        v
    };
    let rows: Vec<Vec<f64>> = t.iter().map(get).collect();
    for c in 0..rows[0].len() {
        let mut x: Vec<f64> = rows.iter().map(|r| r[c]).collect();
        close_loop(&mut x);
        series.push(x);
    }
    // Lateral drift and yaw: the cycle walks straight along +x.
    let mut frames = Vec::with_capacity(n);
    let mut toe_targets = Vec::with_capacity(n);
    let mut max_residual_m: f64 = 0.0;
    let mut q_prev = robot.standing_pose();
    for k in 0..n {
        let s = |c: usize| series[c][k];
        let p_root = Vector3::new(t[k].p_root.x, s(0), s(1));
        let r = UnitQuaternion::from_euler_angles(s(2), s(3), s(4));
        let mut q = LegMap::from_fn(|_| Vector3::zeros());
        let mut p_foot_world = LegMap::from_fn(|_| Vector3::zeros());
        let mut targets = LegMap::from_fn(|_| Vector3::zeros());
        for leg in Leg::ALL {
            let c = 5 + 3 * leg.index();
            let target = Vector3::new(s(c) + p_root.x, s(c + 1) + p_root.y, s(c + 2));
            targets[leg] = target;
            let p_body = r.inverse() * (target - p_root);
            let (ql, residual) = leg_ik(&kin, leg, &p_body, &q_prev[leg]);
            if residual > cfg.max_residual_m {
                return Err(RetargetError::Unreachable {
                    path: clip.path.clone(),
                    frame: start + k,
                    leg: leg.short_name(),
                    marker: cfg.markers.toe[leg],
                    residual_mm: residual * 1e3,
                    allowed_mm: cfg.max_residual_m * 1e3,
                });
            }
            max_residual_m = max_residual_m.max(residual);
            q[leg] = ql;
            p_foot_world[leg] = p_root + r * kin.foot_position_body(leg, &ql);
        }
        q_prev = q;
        toe_targets.push(targets);
        frames.push(MotionFrame {
            p_root_world: p_root,
            r_world_root: r,
            q,
            p_foot_world,
        });
    }
    let name = clip
        .path
        .file_name()
        .map(|s| s.to_string_lossy().to_string())
        .unwrap_or_default();
    let dog_markers = raw
        .iter()
        .map(|m| {
            transform_markers(cfg, m).map(|p| {
                let mut c = to_cycle * (p - origin);
                c.z += lift;
                c
            })
        })
        .collect();
    let motion = ReferenceMotion {
        notes: vec![
            format!("source: {name} frames {start}..{end} (dog motion capture, CC BY-NC 4.0, AI4Animation / Peng et al. 2020)"),
            format!(
                "retarget: scale {}, yaw {:.4} rad, root offset ({}, {}, {}) m, toe outward {} m, hind toe up {} m",
                cfg.scale, cfg.yaw_rad, cfg.root_offset_m.x, cfg.root_offset_m.y, cfg.root_offset_m.z, cfg.toe_outward_m, cfg.hind_toe_up_m
            ),
        ],
        frame_s: MOCAP_FRAME_S,
        frames,
    };
    Ok(Retargeted {
        motion,
        toe_targets,
        dog_markers,
        max_residual_m,
    })
}

/// Which side of the dog a marker is on, averaged over frames: + left, − right (heading frame).
pub fn marker_side(cfg: &RetargetConfig, frames: &[[Vector3<f64>; MARKERS]], marker: usize) -> f64 {
    let ids = &cfg.markers;
    frames
        .iter()
        .map(|raw| {
            let m = transform_markers(cfg, raw);
            let fwd = m[ids.neck] - m[ids.pelvis];
            let left = Vector3::new(-fwd.y, fwd.x, 0.0).normalize();
            let mid = 0.5 * (m[ids.neck] + m[ids.pelvis]);
            (m[marker] - mid).dot(&left)
        })
        .sum::<f64>()
        / frames.len() as f64
}
