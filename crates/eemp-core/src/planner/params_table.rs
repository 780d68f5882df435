//! EEMP-Analytical's lookup table: planner parameters per commanded speed, chosen by the
//! parameter study and looked up at run time (Algorithm 1, "Get planner parameters").

use super::gait::Gait;
use super::params::PlannerParams;
use crate::config_error::{check_range, ConfigError};
use serde::{Deserialize, Serialize};

/// Between tabulated speeds: the nearest entry (the paper's discrete look-up) or linear
/// interpolation of every parameter. Outside the table the end entries are used.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Interpolation {
    #[default]
    Nearest,
    Linear,
}

/// One row: the parameters for `speed_mps`, with the metrics that selected them (informative).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TableEntry {
    pub speed_mps: f64,
    pub swing_time_s: f64,
    pub step_height_m: f64,
    pub body_height_m: f64,
    pub ellipse_rx_m: f64,
    pub ellipse_ry_m: f64,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cot: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub manipulability: Option<f64>,
}

impl TableEntry {
    pub fn new(speed_mps: f64, p: &PlannerParams) -> Self {
        TableEntry {
            speed_mps,
            swing_time_s: p.swing_time_s,
            step_height_m: p.step_height_m,
            body_height_m: p.body_height_m,
            ellipse_rx_m: p.ellipse_rx_m,
            ellipse_ry_m: p.ellipse_ry_m,
            cot: None,
            manipulability: None,
        }
    }

    pub fn params(&self) -> PlannerParams {
        PlannerParams {
            swing_time_s: self.swing_time_s,
            step_height_m: self.step_height_m,
            body_height_m: self.body_height_m,
            ellipse_rx_m: self.ellipse_rx_m,
            ellipse_ry_m: self.ellipse_ry_m,
        }
    }
}

enum Bracket {
    One(usize),
    Between(usize, usize, f64),
}

/// A per-speed parameter table for one gait (a TOML file: `gait`, `interpolation`, `[[entry]]`).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ParamsTable {
    pub gait: Gait,
    #[serde(default)]
    pub interpolation: Interpolation,
    /// Eq. (6)'s progress factor the entries were selected with
    /// ([`super::PlannerConfig::progress_factor`]); `None` if the table does not say. A walk
    /// that uses the table should use this factor too.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub progress_factor: Option<f64>,
    /// The robot the table was selected on (`None`: made before stamps, for the A1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub robot: Option<crate::robot::RobotId>,
    /// The energy the entries' `cot` counts (and the selection minimised); absent: eq. (8).
    #[serde(default, skip_serializing_if = "crate::metrics::CotObjective::is_eq8")]
    pub objective: crate::metrics::CotObjective,
    #[serde(rename = "entry")]
    pub entries: Vec<TableEntry>,
}

impl ParamsTable {
    /// The robot the table was made for (an unstamped table: the A1).
    pub fn robot_id(&self) -> crate::robot::RobotId {
        self.robot
            .clone()
            .unwrap_or_else(crate::robot::RobotId::unstamped)
    }

    /// Sorts the entries by speed and checks them: at least one, distinct finite speeds within
    /// Table I, every parameter within Table I.
    pub fn new(
        gait: Gait,
        interpolation: Interpolation,
        mut entries: Vec<TableEntry>,
    ) -> Result<Self, ConfigError> {
        entries.sort_by(|a, b| a.speed_mps.total_cmp(&b.speed_mps));
        let table = ParamsTable {
            gait,
            interpolation,
            progress_factor: None,
            robot: None,
            objective: Default::default(),
            entries,
        };
        table.validate()?;
        Ok(table)
    }

    pub fn load(path: &std::path::Path) -> Result<Self, ConfigError> {
        let t: ParamsTable = crate::config_error::load_toml(path)?;
        let (robot, objective) = (t.robot, t.objective);
        let table = ParamsTable::new(t.gait, t.interpolation, t.entries);
        match t.progress_factor {
            Some(f) => table.and_then(|table| table.with_progress_factor(f)),
            None => table,
        }
        .map(|table| ParamsTable {
            robot,
            objective,
            ..table
        })
        .map_err(|e| ConfigError::Invalid {
            name: path.display().to_string(),
            message: e.to_string(),
        })
    }

    /// Records the progress factor the table was selected with (checked as
    /// `PlannerConfig::validate` checks it).
    pub fn with_progress_factor(mut self, factor: f64) -> Result<Self, ConfigError> {
        self.progress_factor = Some(factor);
        self.validate()?;
        Ok(self)
    }

    /// The range each parameter of a correction to this table may take (a residual, EEMP-RL):
    /// Table I's, widened to cover the table's own entries. A table selected beyond Table I (the
    /// battery tables' body heights) keeps its values under a zero correction, and a table
    /// inside it keeps Table I's ranges exactly.
    pub fn param_ranges(&self) -> [[f64; 2]; 5] {
        let mut ranges = super::params::TABLE_I_RANGES;
        for e in &self.entries {
            for (r, v) in ranges.iter_mut().zip(e.params().to_array()) {
                r[0] = r[0].min(v);
                r[1] = r[1].max(v);
            }
        }
        ranges
    }

    pub fn to_toml(&self) -> String {
        toml::to_string(self).expect("a table serialises")
    }

    /// This table carried to a robot of `scale`, stamped `robot`: speeds × √λ, every entry's
    /// parameters scaled ([`super::PlannerParams::scaled`]), its measured CoT and
    /// manipulability dropped (they were the other robot's). A first table, not a selection.
    pub fn scaled(&self, scale: &crate::robot::RobotScale, robot: crate::robot::RobotId) -> Self {
        ParamsTable {
            robot: Some(robot),
            entries: self
                .entries
                .iter()
                .map(|e| {
                    TableEntry::new(e.speed_mps * scale.length.sqrt(), &e.params().scaled(scale))
                })
                .collect(),
            ..self.clone()
        }
    }

    pub fn validate(&self) -> Result<(), ConfigError> {
        if let Some(f) = self.progress_factor {
            let [lo, hi] = super::PROGRESS_FACTOR_RANGE;
            check_range("progress_factor", f, lo, hi)?;
        }
        if self.entries.is_empty() {
            return Err(ConfigError::Invalid {
                name: "params table".into(),
                message: "has no [[entry]]".into(),
            });
        }
        let [lo, hi] = super::params::TABLE_SPEED_LIMITS_MPS;
        for (i, e) in self.entries.iter().enumerate() {
            check_range(&format!("entry[{i}].speed_mps"), e.speed_mps, lo, hi)?;
            e.params().validate().map_err(|err| ConfigError::Invalid {
                name: format!("entry[{i}]"),
                message: err.to_string(),
            })?;
            let previous = if i > 0 {
                Some(self.entries[i - 1].speed_mps)
            } else {
                None
            };
            // partial_cmp: a NaN speed never compares Greater, so it is rejected too.
            if previous
                .is_some_and(|p| e.speed_mps.partial_cmp(&p) != Some(std::cmp::Ordering::Greater))
            {
                return Err(ConfigError::Invalid {
                    name: format!("entry[{i}].speed_mps"),
                    message: format!(
                        "speeds must be strictly increasing; {} does not exceed the previous entry",
                        e.speed_mps
                    ),
                });
            }
        }
        Ok(())
    }

    /// Where `speed_mps` falls: one entry (nearest, or outside the table), or between two
    /// with the weight of the second.
    fn bracket(&self, speed_mps: f64) -> Bracket {
        self.bracket_with(speed_mps, self.interpolation)
    }

    fn bracket_with(&self, speed_mps: f64, interpolation: Interpolation) -> Bracket {
        let e = &self.entries;
        let s = if speed_mps.is_finite() {
            speed_mps
        } else {
            0.0
        };
        if s <= e[0].speed_mps {
            return Bracket::One(0);
        }
        if s >= e[e.len() - 1].speed_mps {
            return Bracket::One(e.len() - 1);
        }
        let hi = e
            .iter()
            .position(|x| x.speed_mps >= s)
            .expect("inside the table");
        let (a, b) = (&e[hi - 1], &e[hi]);
        match interpolation {
            Interpolation::Nearest => {
                if s - a.speed_mps <= b.speed_mps - s {
                    Bracket::One(hi - 1)
                } else {
                    Bracket::One(hi)
                }
            }
            Interpolation::Linear => {
                Bracket::Between(hi - 1, hi, (s - a.speed_mps) / (b.speed_mps - a.speed_mps))
            }
        }
    }

    /// The entry nearest to `speed_mps` (the end entries outside the table; ties to the slower).
    pub fn nearest_entry(&self, speed_mps: f64) -> usize {
        match self.bracket_with(speed_mps, Interpolation::Nearest) {
            Bracket::One(i) => i,
            Bracket::Between(a, _, _) => a,
        }
    }

    /// Parameters for a commanded speed (m/s, magnitude of the horizontal command).
    pub fn lookup(&self, speed_mps: f64) -> PlannerParams {
        let e = &self.entries;
        match self.bracket(speed_mps) {
            Bracket::One(i) => e[i].params(),
            Bracket::Between(a, b, w) => {
                let (pa, pb) = (e[a].params(), e[b].params());
                let mix = |x: f64, y: f64| x + w * (y - x);
                PlannerParams {
                    swing_time_s: mix(pa.swing_time_s, pb.swing_time_s),
                    step_height_m: mix(pa.step_height_m, pb.step_height_m),
                    body_height_m: mix(pa.body_height_m, pb.body_height_m),
                    ellipse_rx_m: mix(pa.ellipse_rx_m, pb.ellipse_rx_m),
                    ellipse_ry_m: mix(pa.ellipse_ry_m, pb.ellipse_ry_m),
                }
            }
        }
    }

    /// The selection metrics (CoT, manipulability) recorded for a commanded speed, by the same
    /// rule as [`ParamsTable::lookup`]; None where an entry it uses has none.
    pub fn metrics_at(&self, speed_mps: f64) -> Option<(f64, f64)> {
        let e = &self.entries;
        let m = |i: usize| Some((e[i].cot?, e[i].manipulability?));
        match self.bracket(speed_mps) {
            Bracket::One(i) => m(i),
            Bracket::Between(a, b, w) => {
                let ((ca, ma), (cb, mb)) = (m(a)?, m(b)?);
                Some((ca + w * (cb - ca), ma + w * (mb - ma)))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn param_ranges_are_table_i_widened_to_the_entries() {
        let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../..");
        let inside = ParamsTable::load(&root.join("tables/a1_free.toml")).unwrap();
        assert_eq!(inside.param_ranges(), super::super::params::TABLE_I_RANGES);
        let battery = ParamsTable::load(&root.join("tables/a1_free_battery.toml")).unwrap();
        let r = battery.param_ranges();
        let top = battery
            .entries
            .iter()
            .map(|e| e.params().body_height_m)
            .fold(f64::MIN, f64::max);
        assert!(top > super::super::params::table_i::BODY_HEIGHT_M[1]);
        assert_eq!(r[2], [super::super::params::table_i::BODY_HEIGHT_M[0], top]);
        // A zero correction keeps every entry as it is.
        for e in &battery.entries {
            assert_eq!(e.params().offset_within(&[0.0; 5], &r), e.params());
        }
    }

    use super::*;

    fn table(interpolation: Interpolation) -> ParamsTable {
        let a = PlannerParams {
            swing_time_s: 0.25,
            ellipse_rx_m: 0.10,
            ..Default::default()
        };
        let b = PlannerParams {
            swing_time_s: 0.15,
            ellipse_rx_m: 0.04,
            ..Default::default()
        };
        ParamsTable::new(
            Gait::Trot,
            interpolation,
            vec![TableEntry::new(0.5, &b), TableEntry::new(0.1, &a)],
        )
        .unwrap()
    }

    #[test]
    fn nearest_and_linear_lookup_by_hand() {
        let t = table(Interpolation::Nearest);
        assert_eq!(t.entries[0].speed_mps, 0.1, "sorted on construction");
        assert_eq!(t.lookup(0.05).swing_time_s, 0.25);
        assert_eq!(t.lookup(0.29).swing_time_s, 0.25);
        assert_eq!(t.lookup(0.31).swing_time_s, 0.15);
        assert_eq!(t.lookup(2.0).swing_time_s, 0.15);
        let t = table(Interpolation::Linear);
        // 0.2 m/s is a quarter of the way from 0.1 to 0.5: 0.25 − 0.25·0.10 = 0.225 s.
        assert!((t.lookup(0.2).swing_time_s - 0.225).abs() < 1e-12);
        assert!((t.lookup(0.2).ellipse_rx_m - 0.085).abs() < 1e-12);
        assert_eq!(t.lookup(f64::NAN).swing_time_s, 0.25);
    }

    #[test]
    fn the_progress_factor_is_kept_through_a_file_and_checked() {
        let t = table(Interpolation::Nearest);
        assert_eq!(t.progress_factor, None);
        assert!(
            !t.to_toml().contains("progress_factor"),
            "absent means absent"
        );
        let t = t.with_progress_factor(1.5).unwrap();
        let path = std::env::temp_dir().join(format!("eemp-table-pf-{}.toml", std::process::id()));
        std::fs::write(&path, t.to_toml()).unwrap();
        let back = ParamsTable::load(&path).unwrap();
        std::fs::remove_file(&path).unwrap();
        assert_eq!(back.progress_factor, Some(1.5));
        assert_eq!(back, t);
        let e = table(Interpolation::Nearest)
            .with_progress_factor(2.5)
            .unwrap_err()
            .to_string();
        assert!(e.contains("progress_factor") && e.contains("2.5"), "{e}");
        // From a file, the error names the file.
        let bad = path.with_extension("bad.toml");
        std::fs::write(&bad, t.to_toml().replace("1.5", "2.5")).unwrap();
        let e = ParamsTable::load(&bad).unwrap_err().to_string();
        std::fs::remove_file(&bad).unwrap();
        assert!(e.contains("bad.toml") && e.contains("2.5"), "{e}");
    }

    #[test]
    fn round_trips_through_toml_and_rejects_bad_tables() {
        let t = table(Interpolation::Linear);
        let back: ParamsTable = toml::from_str(&t.to_toml()).unwrap();
        assert_eq!(back, t);
        let dup = ParamsTable::new(
            Gait::Walk,
            Interpolation::Nearest,
            vec![
                TableEntry::new(0.1, &PlannerParams::default()),
                TableEntry::new(0.1, &PlannerParams::default()),
            ],
        );
        assert!(dup.unwrap_err().to_string().contains("strictly increasing"));
        let bad = ParamsTable::new(
            Gait::Walk,
            Interpolation::Nearest,
            vec![TableEntry::new(
                0.1,
                &PlannerParams {
                    swing_time_s: 1.5,
                    ..Default::default()
                },
            )],
        );
        assert!(bad.unwrap_err().to_string().contains("swing_time_s"));
        assert!(ParamsTable::new(Gait::Walk, Interpolation::Nearest, vec![]).is_err());
    }
}
