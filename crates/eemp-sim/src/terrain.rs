//! Terrain beyond the flat floor, generated into the MJCF from a description (seeded, so the
//! same file gives the same ground): a rough height field, a ramp up and down, a step up or
//! down, a staircase, and patches of another friction. [`Terrain::height_at`] says where the
//! ground is. Ground that goes down from the start (a step down, stairs down) is built as a
//! platform the robot starts on, so the floor stays MuJoCo's plane at z = 0.

use crate::mjcf::SceneExtras;
use eemp_core::config_error::{check_range, ConfigError};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde::{Deserialize, Serialize};
use std::fmt::Write;

/// Contact softness shared with the floor (Menagerie's foot solimp).
const SOLIMP: &str = "0.015 1 0.031";

/// Contact softness of the rough height field: MuJoCo's default, stiff. With the floor's soft
/// [`SOLIMP`] (impedance 0.015 at first touch, full only after 3.1 cm) a loaded 2 cm foot sinks
/// more than a centimetre into the field, and MuJoCo's per-prism collision then reports the
/// walls of the neighbouring cells (horizontal normals, 2 cm deep) instead of the surface: they
/// squeeze the foot and friction holds it, so a swing leg pulling with 20 N·m at hip and knee
/// stays where it is for its whole swing and the robot trips over it. Stiff contact keeps the
/// foot on the surface, and all three EEMP gaits walk ±2 cm ground with it.
const HFIELD_SOLIMP: &str = "0.9 0.95 0.001";

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Rough {
    /// Heights span ±amplitude, m.
    pub amplitude_m: f64,
    /// Distance between independent heights, m.
    pub wavelength_m: f64,
    pub seed: u64,
    /// Side of the square field centred on the start, m.
    #[serde(default = "Rough::default_size")]
    pub size_m: f64,
}

impl Rough {
    fn default_size() -> f64 {
        16.0
    }
}

/// A ramp up at `grade` from `start_x_m`, a plateau, and a ramp down at the same grade.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Ramp {
    pub start_x_m: f64,
    /// Rise over run (0.1 = 10 %).
    pub grade: f64,
    pub rise_m: f64,
    pub plateau_m: f64,
}

/// The ground rises by `height_m` from `at_x_m` on (for 10 m); a negative height is a step
/// down.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    pub at_x_m: f64,
    pub height_m: f64,
}

/// A staircase from `at_x_m`: `count` steps of `rise_m` (negative: down) every `run_m`, then a
/// landing (10 m).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stairs {
    pub at_x_m: f64,
    pub rise_m: f64,
    pub run_m: f64,
    pub count: usize,
}

/// How far the step and the stairs reach beyond their last edge, m.
const LANDING_M: f64 = 10.0;

/// A patch of other friction on the floor between `x0_m` and `x1_m`, `width_m` wide.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionPatch {
    pub x0_m: f64,
    pub x1_m: f64,
    #[serde(default = "FrictionPatch::default_width")]
    pub width_m: f64,
    pub friction: f64,
}

impl FrictionPatch {
    fn default_width() -> f64 {
        4.0
    }
}

#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Terrain {
    #[serde(default)]
    pub rough: Option<Rough>,
    #[serde(default)]
    pub ramp: Option<Ramp>,
    #[serde(default)]
    pub step: Option<Step>,
    #[serde(default)]
    pub stairs: Option<Stairs>,
    #[serde(default)]
    pub friction_patch: Vec<FrictionPatch>,
}

/// Half thickness of a friction patch's mat, m.
const PATCH_HALF_M: f64 = 0.0015;

/// Height-field grid spacing, m.
const CELL_M: f64 = 0.05;

/// Grid points per side and their actual spacing (the size need not be a multiple of CELL_M).
fn grid(size_m: f64) -> (usize, f64) {
    let n = (size_m / CELL_M).round() as usize + 1;
    (n, size_m / (n - 1) as f64)
}

impl Terrain {
    pub fn validate(&self) -> Result<(), ConfigError> {
        if let Some(r) = &self.rough {
            check_range("terrain.rough.amplitude_m", r.amplitude_m, 0.001, 0.1)?;
            check_range("terrain.rough.wavelength_m", r.wavelength_m, 0.1, 5.0)?;
            check_range("terrain.rough.size_m", r.size_m, 1.0, 40.0)?;
        }
        if let Some(r) = &self.ramp {
            check_range("terrain.ramp.start_x_m", r.start_x_m, 0.3, 100.0)?;
            check_range("terrain.ramp.grade", r.grade, 0.01, 0.5)?;
            check_range("terrain.ramp.rise_m", r.rise_m, 0.01, 2.0)?;
            check_range("terrain.ramp.plateau_m", r.plateau_m, 0.0, 100.0)?;
        }
        if let Some(s) = &self.step {
            check_range("terrain.step.at_x_m", s.at_x_m, 0.3, 100.0)?;
            check_range("terrain.step.height_m", s.height_m, -0.2, 0.2)?;
            if s.height_m.abs() < 0.005 {
                return Err(ConfigError::Invalid {
                    name: "terrain.step.height_m".into(),
                    message: format!(
                        "{} is no step: allowed [-0.2, -0.005] (down) or [0.005, 0.2] (up)",
                        s.height_m
                    ),
                });
            }
        }
        if let Some(s) = &self.stairs {
            check_range("terrain.stairs.at_x_m", s.at_x_m, 0.3, 100.0)?;
            check_range("terrain.stairs.rise_m", s.rise_m, -0.25, 0.25)?;
            if s.rise_m.abs() < 0.005 {
                return Err(ConfigError::Invalid {
                    name: "terrain.stairs.rise_m".into(),
                    message: format!(
                        "{} is no rise: allowed [-0.25, -0.005] (down) or [0.005, 0.25] (up)",
                        s.rise_m
                    ),
                });
            }
            check_range("terrain.stairs.run_m", s.run_m, 0.1, 5.0)?;
            check_range("terrain.stairs.count", s.count as f64, 1.0, 50.0)?;
        }
        if self.step.is_some() && self.stairs.is_some() {
            return Err(ConfigError::Invalid {
                name: "terrain.stairs".into(),
                message: "a staircase cannot be combined with a step (give one)".into(),
            });
        }
        if self.ramp.is_some() && self.start_lift_m() > 0.0 {
            return Err(ConfigError::Invalid {
                name: "terrain.ramp".into(),
                message: "a ramp cannot be combined with ground that goes down from the start \
                          (a step or stairs down)"
                    .into(),
            });
        }
        for (i, p) in self.friction_patch.iter().enumerate() {
            check_range(
                &format!("terrain.friction_patch[{i}].x0_m"),
                p.x0_m,
                -100.0,
                100.0,
            )?;
            check_range(
                &format!("terrain.friction_patch[{i}].x1_m"),
                p.x1_m,
                p.x0_m + 0.01,
                200.0,
            )?;
            check_range(
                &format!("terrain.friction_patch[{i}].width_m"),
                p.width_m,
                0.1,
                40.0,
            )?;
            eemp_core::config_error::check_friction(
                &format!("terrain.friction_patch[{i}].friction"),
                p.friction,
            )?;
            // Segments of other friction along the path: in order, none overlapping another
            // (where two overlapped, which friction holds would be MuJoCo's choice).
            if i > 0 {
                let prev = &self.friction_patch[i - 1];
                if p.x0_m < prev.x1_m {
                    return Err(ConfigError::Invalid {
                        name: format!("terrain.friction_patch[{i}].x0_m"),
                        message: format!(
                            "{} starts before patch {} ends at x1_m = {}: patches must be in \
                             order along x and not overlap",
                            p.x0_m,
                            i - 1,
                            prev.x1_m
                        ),
                    });
                }
            }
        }
        let shaped = self.ramp.is_some() || self.step.is_some() || self.stairs.is_some();
        if self.rough.is_some() && shaped {
            return Err(ConfigError::Invalid {
                name: "terrain".into(),
                message: "a rough field cannot be combined with a ramp, a step or stairs".into(),
            });
        }
        if !self.friction_patch.is_empty() && (self.rough.is_some() || shaped) {
            return Err(ConfigError::Invalid {
                name: "terrain.friction_patch".into(),
                message: "patches lie on the flat floor: they cannot be combined with rough \
                          ground, a ramp, a step or stairs"
                    .into(),
            });
        }
        Ok(())
    }

    /// The rough field's heights, row-major (y rows, x columns), and its grid size.
    fn rough_grid(r: &Rough) -> (usize, Vec<f64>) {
        let (n, cell) = grid(r.size_m);
        // Random heights on a lattice of the wavelength, smoothly interpolated (value noise).
        let m = (r.size_m / r.wavelength_m).ceil() as usize + 2;
        let mut rng = ChaCha8Rng::seed_from_u64(r.seed);
        let lattice: Vec<f64> = (0..m * m).map(|_| rng.random_range(-1.0..1.0)).collect();
        let smooth = |t: f64| t * t * (3.0 - 2.0 * t);
        let mut h = vec![0.0; n * n];
        for iy in 0..n {
            for ix in 0..n {
                let (u, v) = (
                    ix as f64 * cell / r.wavelength_m,
                    iy as f64 * cell / r.wavelength_m,
                );
                let (i, j) = (u.floor() as usize, v.floor() as usize);
                let (fu, fv) = (smooth(u - i as f64), smooth(v - j as f64));
                let at = |a: usize, b: usize| lattice[(b.min(m - 1)) * m + a.min(m - 1)];
                let top = at(i, j) * (1.0 - fu) + at(i + 1, j) * fu;
                let bot = at(i, j + 1) * (1.0 - fu) + at(i + 1, j + 1) * fu;
                h[iy * n + ix] = r.amplitude_m * (top * (1.0 - fv) + bot * fv);
            }
        }
        // The start is level (z = 0 within 0.5 m of the centre, blending in by 1 m), so the
        // robot is put down on flat ground and walks onto the roughness.
        let half = r.size_m / 2.0;
        for iy in 0..n {
            for ix in 0..n {
                let d = (ix as f64 * cell - half).hypot(iy as f64 * cell - half);
                let w = ((d - 0.5) / 0.5).clamp(0.0, 1.0);
                h[iy * n + ix] *= w * w * (3.0 - 2.0 * w);
            }
        }
        (n, h)
    }

    /// The step's or the stairs' ground as flat pieces (x from, length, height relative to the
    /// start's ground), in order along x; empty without either.
    fn levels(&self) -> Vec<(f64, f64, f64)> {
        if let Some(s) = &self.step {
            return vec![(s.at_x_m, LANDING_M, s.height_m)];
        }
        if let Some(s) = &self.stairs {
            return (0..s.count)
                .map(|i| {
                    let len = if i + 1 == s.count { LANDING_M } else { s.run_m };
                    (
                        s.at_x_m + i as f64 * s.run_m,
                        len,
                        (i + 1) as f64 * s.rise_m,
                    )
                })
                .collect();
        }
        Vec::new()
    }

    /// How high the start's ground stands above the floor plane, m: the platform under the
    /// start where the ground goes down from it (0 otherwise).
    pub fn start_lift_m(&self) -> f64 {
        -self.levels().iter().map(|l| l.2).fold(0.0_f64, f64::min)
    }

    /// The flat pieces above the floor plane as they are built: (x from, length, height), the
    /// start's platform first.
    fn built_levels(&self) -> Vec<(f64, f64, f64)> {
        let lift = self.start_lift_m();
        let levels = self.levels();
        let mut out = Vec::new();
        if lift > 0.0 {
            // From behind the start to the first edge, wherever that is.
            let first = levels.first().map_or(0.0, |l| l.0);
            out.push((-LANDING_M, first + LANDING_M, lift));
        }
        out.extend(
            levels
                .into_iter()
                .map(|(a, b, z)| (a, b, z + lift))
                .filter(|l| l.2 > 1e-9),
        );
        out
    }

    /// Ground height at (x, y), m (what a resting foot or sphere sits on). For many queries,
    /// [`Ground`] computes the rough field once.
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        Ground::new(self).height_at(x, y)
    }

    /// [`Terrain::height_at`] with the rough field's grid and the built levels computed.
    fn height_with(
        &self,
        rough: Option<&(usize, Vec<f64>)>,
        levels: &[(f64, f64, f64)],
        x: f64,
        y: f64,
    ) -> f64 {
        let mut z: f64 = 0.0;
        if let (Some(r), Some((n, h))) = (&self.rough, rough) {
            let n = *n;
            let half = r.size_m / 2.0;
            if x.abs() <= half && y.abs() <= half {
                let cell = grid(r.size_m).1;
                let (u, v) = ((x + half) / cell, (y + half) / cell);
                let (i, j) = (
                    (u.floor() as usize).min(n - 2),
                    (v.floor() as usize).min(n - 2),
                );
                let (fu, fv) = (u - i as f64, v - j as f64);
                let at = |a: usize, b: usize| h[b * n + a];
                // MuJoCo splits each cell into two triangles along the (i,j)–(i+1,j+1) diagonal.
                z = if fu >= fv {
                    at(i, j)
                        + fu * (at(i + 1, j) - at(i, j))
                        + fv * (at(i + 1, j + 1) - at(i + 1, j))
                } else {
                    at(i, j)
                        + fv * (at(i, j + 1) - at(i, j))
                        + fu * (at(i + 1, j + 1) - at(i, j + 1))
                };
            } else {
                z = Self::rough_floor(r);
            }
        }
        if let Some(r) = &self.ramp {
            let run = r.rise_m / r.grade;
            let d = x - r.start_x_m;
            z = z.max(if d <= 0.0 {
                0.0
            } else if d <= run {
                d * r.grade
            } else if d <= run + r.plateau_m {
                r.rise_m
            } else {
                (r.rise_m - (d - run - r.plateau_m) * r.grade).max(0.0)
            });
        }
        for &(x0, len, h) in levels {
            if x >= x0 && x <= x0 + len {
                z = z.max(h);
            }
        }
        for p in &self.friction_patch {
            if x >= p.x0_m && x <= p.x1_m && y.abs() <= p.width_m / 2.0 {
                z = z.max(2.0 * PATCH_HALF_M);
            }
        }
        z
    }

    fn rough_floor(r: &Rough) -> f64 {
        -r.amplitude_m * 2.0 - 0.01
    }

    /// The MJCF pieces of this terrain; `floor_friction` is the robot file's.
    pub fn scene(&self, floor_friction: f64) -> SceneExtras {
        let mut x = SceneExtras::default();
        let geom = |name: &str, body: &str, mu: f64, priority: u8, solimp: &str| {
            format!(
                r#"    <geom name="{name}" {body} contype="1" conaffinity="1" priority="{priority}" condim="3" friction="{mu} 0.02 0.01" solimp="{solimp}" rgba="0.7 0.7 0.75 1"/>
"#
            )
        };
        if let Some(r) = &self.rough {
            let (n, h) = Self::rough_grid(r);
            let (lo, hi) = h
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &z| {
                    (a.min(z), b.max(z))
                });
            let span = (hi - lo).max(1e-6);
            let mut elev = String::with_capacity(n * n * 7);
            // MuJoCo's first elevation row is the field's +y edge.
            for row in h.chunks(n).rev() {
                for z in row {
                    write!(elev, "{:.5} ", (z - lo) / span).unwrap();
                }
            }
            write!(
                x.assets_xml,
                r#"<hfield name="rough" nrow="{n}" ncol="{n}" size="{half} {half} {span} 0.05" elevation="{elev}"/>"#,
                half = r.size_m / 2.0,
            )
            .unwrap();
            x.world_geoms_xml += &geom(
                "terrain_rough",
                &format!(r#"type="hfield" hfield="rough" pos="0 0 {lo}""#),
                floor_friction,
                1,
                HFIELD_SOLIMP,
            );
            x.floor_z_m = Self::rough_floor(r);
        }
        if let Some(r) = &self.ramp {
            let run = r.rise_m / r.grade;
            let theta = r.grade.atan();
            let len = run.hypot(r.rise_m);
            let t = 0.05; // half thickness
                          // A tilted box whose top face runs along the ramp surface.
            for (name, cx, sign) in [
                ("terrain_ramp_up", r.start_x_m + run / 2.0, -1.0),
                (
                    "terrain_ramp_down",
                    r.start_x_m + 1.5 * run + r.plateau_m,
                    1.0,
                ),
            ] {
                let (cz, cxo) = (r.rise_m / 2.0 - t * theta.cos(), -sign * t * theta.sin());
                x.world_geoms_xml += &geom(
                    name,
                    &format!(
                        r#"type="box" size="{} 4 {t}" pos="{} 0 {cz}" euler="0 {} 0""#,
                        len / 2.0,
                        cx + cxo,
                        sign * theta
                    ),
                    floor_friction,
                    1,
                    SOLIMP,
                );
            }
            if r.plateau_m > 0.0 {
                x.world_geoms_xml += &geom(
                    "terrain_plateau",
                    &format!(
                        r#"type="box" size="{} 4 {}" pos="{} 0 {}""#,
                        r.plateau_m / 2.0,
                        r.rise_m / 2.0,
                        r.start_x_m + run + r.plateau_m / 2.0,
                        r.rise_m / 2.0
                    ),
                    floor_friction,
                    1,
                    SOLIMP,
                );
            }
        }
        for (i, (x0, len, h)) in self.built_levels().into_iter().enumerate() {
            // The step up keeps its name (one piece); the others are numbered along x.
            let name = match (&self.step, i) {
                (Some(s), 0) if s.height_m > 0.0 => "terrain_step".to_string(),
                _ => format!("terrain_level_{i}"),
            };
            x.world_geoms_xml += &geom(
                &name,
                &format!(
                    r#"type="box" size="{} 4 {}" pos="{} 0 {}""#,
                    len / 2.0,
                    h / 2.0,
                    x0 + len / 2.0,
                    h / 2.0
                ),
                floor_friction,
                1,
                SOLIMP,
            );
        }
        for (i, p) in self.friction_patch.iter().enumerate() {
            // A 3 mm mat with a stiff surface (a loaded foot sinks ~1 mm into it, not the 17 mm
            // of the soft floor), so the feet on it touch only it and its friction is the one.
            x.world_geoms_xml += &format!(
                r#"    <geom name="terrain_patch_{i}" type="box" size="{} {} {PATCH_HALF_M}" pos="{} 0 {PATCH_HALF_M}" contype="1" conaffinity="1" priority="2" condim="3" friction="{} 0.02 0.01" solref="0.004 1" solimp="0.95 0.99 0.001" rgba="0.5 0.6 0.9 1"/>
"#,
                (p.x1_m - p.x0_m) / 2.0,
                p.width_m / 2.0,
                (p.x0_m + p.x1_m) / 2.0,
                p.friction,
            );
        }
        x
    }
}

/// A terrain ready for many height queries (the closed loop's fall check at every step): the
/// rough field's grid and the steps' levels computed once.
#[derive(Clone, Debug)]
pub struct Ground {
    terrain: Terrain,
    grid: Option<(usize, Vec<f64>)>,
    levels: Vec<(f64, f64, f64)>,
}

impl Ground {
    pub fn new(terrain: &Terrain) -> Self {
        Ground {
            grid: terrain.rough.as_ref().map(Terrain::rough_grid),
            levels: terrain.built_levels(),
            terrain: terrain.clone(),
        }
    }

    /// [`Terrain::height_at`].
    pub fn height_at(&self, x: f64, y: f64) -> f64 {
        self.terrain
            .height_with(self.grid.as_ref(), &self.levels, x, y)
    }
}
