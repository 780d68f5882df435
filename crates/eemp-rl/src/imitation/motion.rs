//! A reference motion for the A1: the project's file format and its loop.
//!
//! File: CSV, `#` lines first (provenance), then a header and one row per frame:
//! `t_s, root_{x,y,z}_m, root_q{w,x,y,z}` (world, wxyz), 12 joint angles (actuator order FR, FL,
//! RR, RL; abduction, thigh, calf; rad), 4 foot positions (world, m; foot-sphere centres from
//! forward kinematics of the joint angles at the root pose). Frames are evenly spaced. A motion
//! is one gait cycle: frame N (one past the last) is frame 0 moved by the cycle's displacement.

use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use nalgebra::{UnitQuaternion, Vector3};
use std::path::{Path, PathBuf};

pub const COLUMNS: usize = 1 + 3 + 4 + 12 + 12;

/// Contact detection of a reference (see [`ReferenceMotion::contacts`]): the capture's stance
/// toes rise by up to ~2 cm as the paw rolls, so height alone is too strict.
pub const CONTACT_HEIGHT_M: f64 = 0.03;
pub const CONTACT_SPEED_MPS: f64 = 0.3;

#[derive(Clone, Debug, PartialEq)]
pub struct MotionFrame {
    pub p_root_world: Vector3<f64>,
    pub r_world_root: UnitQuaternion<f64>,
    pub q: LegMap<Vector3<f64>>,
    pub p_foot_world: LegMap<Vector3<f64>>,
}

#[derive(Clone, Debug, PartialEq)]
pub struct ReferenceMotion {
    /// Provenance lines (without the leading '#').
    pub notes: Vec<String>,
    pub frame_s: f64,
    pub frames: Vec<MotionFrame>,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MotionError {
    #[error("cannot read {path}: {message}")]
    Io { path: PathBuf, message: String },
    #[error("{path}: line {line}: {message}")]
    Malformed {
        path: PathBuf,
        line: usize,
        message: String,
    },
    #[error("{path}: {message}")]
    Invalid { path: PathBuf, message: String },
}

fn header() -> Vec<String> {
    let mut h: Vec<String> = ["t_s", "root_x_m", "root_y_m", "root_z_m"]
        .iter()
        .map(|s| s.to_string())
        .collect();
    h.extend(["root_qw", "root_qx", "root_qy", "root_qz"].map(String::from));
    for leg in Leg::ALL {
        for j in ["abduction", "thigh", "calf"] {
            h.push(format!("q_{}_{j}_rad", leg.short_name()));
        }
    }
    for leg in Leg::ALL {
        for a in ["x", "y", "z"] {
            h.push(format!("foot_{}_{a}_m", leg.short_name()));
        }
    }
    h
}

impl ReferenceMotion {
    /// Cycle duration, s (N frame periods: the loop closes one period after the last frame).
    pub fn cycle_s(&self) -> f64 {
        self.frames.len() as f64 * self.frame_s
    }

    /// Root displacement over one cycle (world), from the mean velocity over the frames.
    pub fn cycle_displacement(&self) -> Vector3<f64> {
        let n = self.frames.len();
        let d = self.frames[n - 1].p_root_world - self.frames[0].p_root_world;
        let mut d = d * n as f64 / (n - 1) as f64;
        d.z = 0.0;
        d
    }

    /// Mean horizontal speed of the root, m/s.
    pub fn speed_mps(&self) -> f64 {
        self.cycle_displacement().xy().norm() / self.cycle_s()
    }

    /// Which feet are on the ground in each frame: foot centre within `height_tol_m` of the
    /// lowest it gets in the clip and moving slower than `speed_tol_mps` (world).
    pub fn contacts(&self, height_tol_m: f64, speed_tol_mps: f64) -> Vec<LegMap<bool>> {
        let n = self.frames.len();
        let lowest = LegMap::from_fn(|leg| {
            self.frames
                .iter()
                .map(|f| f.p_foot_world[leg].z)
                .fold(f64::INFINITY, f64::min)
        });
        let disp = self.cycle_displacement();
        (0..n)
            .map(|k| {
                let (a, b) = (k, (k + 1) % n);
                LegMap::from_fn(|leg| {
                    let pa = self.frames[a].p_foot_world[leg];
                    let mut pb = self.frames[b].p_foot_world[leg];
                    if b == 0 {
                        pb += disp;
                    }
                    let speed = (pb - pa).xy().norm() / self.frame_s;
                    pa.z <= lowest[leg] + height_tol_m && speed <= speed_tol_mps
                })
            })
            .collect()
    }

    pub fn save(&self, path: &Path) -> Result<(), MotionError> {
        let mut s = String::new();
        for n in &self.notes {
            s.push_str(&format!("# {n}\n"));
        }
        s.push_str(&header().join(","));
        s.push('\n');
        for (k, f) in self.frames.iter().enumerate() {
            let q = f.r_world_root.coords;
            let mut row = vec![k as f64 * self.frame_s];
            row.extend(f.p_root_world.iter());
            row.extend([q.w, q.x, q.y, q.z]);
            for leg in Leg::ALL {
                row.extend(f.q[leg].iter());
            }
            for leg in Leg::ALL {
                row.extend(f.p_foot_world[leg].iter());
            }
            let cells: Vec<String> = row.iter().map(|v| format!("{v:.6}")).collect();
            s.push_str(&cells.join(","));
            s.push('\n');
        }
        std::fs::write(path, s).map_err(|e| MotionError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })
    }

    pub fn load(path: &Path) -> Result<Self, MotionError> {
        let text = std::fs::read_to_string(path).map_err(|e| MotionError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        })?;
        Self::parse(path, &text)
    }

    pub fn parse(path: &Path, text: &str) -> Result<Self, MotionError> {
        let bad = |line: usize, message: String| MotionError::Malformed {
            path: path.to_path_buf(),
            line,
            message,
        };
        let mut notes = Vec::new();
        let mut rows: Vec<(usize, Vec<f64>)> = Vec::new();
        let mut saw_header = false;
        for (l, line) in text.lines().enumerate() {
            let line = line.trim();
            if line.is_empty() {
                continue;
            }
            if let Some(n) = line.strip_prefix('#') {
                notes.push(n.trim().to_string());
                continue;
            }
            if !saw_header {
                if line
                    .split(',')
                    .map(str::trim)
                    .ne(header().iter().map(String::as_str))
                {
                    return Err(bad(
                        l + 1,
                        format!("expected the header '{}'", header().join(",")),
                    ));
                }
                saw_header = true;
                continue;
            }
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != COLUMNS {
                return Err(bad(
                    l + 1,
                    format!("{} columns, expected {COLUMNS}", cells.len()),
                ));
            }
            let mut v = Vec::with_capacity(COLUMNS);
            for (c, cell) in cells.iter().enumerate() {
                match cell.parse::<f64>() {
                    Ok(x) if x.is_finite() => v.push(x),
                    _ => {
                        return Err(bad(
                            l + 1,
                            format!(
                                "column {} ('{}') = '{cell}' is not a finite number",
                                c + 1,
                                header()[c]
                            ),
                        ))
                    }
                }
            }
            rows.push((l + 1, v));
        }
        let invalid = |message: String| MotionError::Invalid {
            path: path.to_path_buf(),
            message,
        };
        if rows.len() < 3 {
            return Err(invalid(format!(
                "{} frames: a motion needs at least 3",
                rows.len()
            )));
        }
        let frame_s = rows[1].1[0] - rows[0].1[0];
        if !(1e-4..=1.0).contains(&frame_s) {
            return Err(invalid(format!(
                "frame period {frame_s} s out of range: allowed [0.0001, 1]"
            )));
        }
        let mut frames = Vec::with_capacity(rows.len());
        for (k, (line, v)) in rows.iter().enumerate() {
            if (v[0] - k as f64 * frame_s).abs() > 1e-4 {
                return Err(bad(
                    *line,
                    format!("t_s = {} breaks the even spacing of {frame_s} s", v[0]),
                ));
            }
            let qn = (v[4] * v[4] + v[5] * v[5] + v[6] * v[6] + v[7] * v[7]).sqrt();
            if (qn - 1.0).abs() > 1e-3 {
                return Err(bad(*line, format!("root quaternion norm {qn}: expected 1")));
            }
            let r =
                UnitQuaternion::from_quaternion(nalgebra::Quaternion::new(v[4], v[5], v[6], v[7]));
            frames.push(MotionFrame {
                p_root_world: Vector3::new(v[1], v[2], v[3]),
                r_world_root: r,
                q: LegMap::from_fn(|leg| {
                    let k = 8 + 3 * leg.index();
                    Vector3::new(v[k], v[k + 1], v[k + 2])
                }),
                p_foot_world: LegMap::from_fn(|leg| {
                    let k = 20 + 3 * leg.index();
                    Vector3::new(v[k], v[k + 1], v[k + 2])
                }),
            });
        }
        Ok(ReferenceMotion {
            notes,
            frame_s,
            frames,
        })
    }

    /// Checks the file against the robot: joint angles within the ranges, feet where forward
    /// kinematics puts them (so a motion made for another robot is refused), and a cycle that
    /// travels (the reference is scaled by its speed).
    pub fn check_against(&self, kin: &LegKinematics, path: &Path) -> Result<(), MotionError> {
        let speed = self.speed_mps();
        if speed.is_nan() || speed <= 0.01 {
            return Err(MotionError::Invalid {
                path: path.to_path_buf(),
                message: format!(
                    "the cycle travels at {:.4} m/s: a reference gait must move (> 0.01 m/s)",
                    self.speed_mps()
                ),
            });
        }
        for (k, f) in self.frames.iter().enumerate() {
            for leg in Leg::ALL {
                for j in 0..3 {
                    let [lo, hi] = kin.joint_range(leg, j);
                    let q = f.q[leg][j];
                    if q < lo - 1e-6 || q > hi + 1e-6 {
                        return Err(MotionError::Invalid {
                            path: path.to_path_buf(),
                            message: format!(
                                "frame {k}: joint {j} of {} = {q:.4} rad outside its range [{lo}, {hi}]",
                                leg.short_name()
                            ),
                        });
                    }
                }
                let fk = f.p_root_world + f.r_world_root * kin.foot_position_body(leg, &f.q[leg]);
                let err = (fk - f.p_foot_world[leg]).norm();
                if err > 2e-3 {
                    return Err(MotionError::Invalid {
                        path: path.to_path_buf(),
                        message: format!(
                            "frame {k}: foot {} is {:.1} mm from where this robot's kinematics put it (another robot's motion?)",
                            leg.short_name(),
                            err * 1e3
                        ),
                    });
                }
            }
        }
        Ok(())
    }
}

/// Fraction of frames in which legs `a` and `b` are both in contact or both in the air.
pub fn pair_agreement(contacts: &[LegMap<bool>], a: Leg, b: Leg) -> f64 {
    let same = contacts.iter().filter(|c| c[a] == c[b]).count();
    same as f64 / contacts.len().max(1) as f64
}

/// The gait a contact pattern shows: "trot" (diagonal pairs together), "pace" (lateral
/// pairs), "bound" (front and rear pairs), or "other" (no pair agrees in ≥ 75 % of frames).
pub fn gait_of(contacts: &[LegMap<bool>]) -> &'static str {
    use Leg::*;
    let score = |(a, b): (Leg, Leg), (c, d): (Leg, Leg)| {
        pair_agreement(contacts, a, b).min(pair_agreement(contacts, c, d))
    };
    let candidates = [
        (
            "trot",
            score((FrontRight, RearLeft), (FrontLeft, RearRight)),
        ),
        (
            "pace",
            score((FrontRight, RearRight), (FrontLeft, RearLeft)),
        ),
        (
            "bound",
            score((FrontRight, FrontLeft), (RearRight, RearLeft)),
        ),
    ];
    let best = candidates
        .iter()
        .max_by(|x, y| x.1.total_cmp(&y.1))
        .expect("three candidates");
    if best.1 >= 0.75 {
        best.0
    } else {
        "other"
    }
}
