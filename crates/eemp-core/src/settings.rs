//! The controller's settings as one tree of data: what `eemp walk --set key=value`, a run file's
//! or a suite method's `set = [...]` and `eemp config show` address.
//!
//! The tree has one table per part of the pipeline, each the serialised form of that part's own
//! config struct, so every field of those structs is a key and their own validation names the
//! value and its range:
//!
//! | table | struct | what it holds |
//! |---|---|---|
//! | `planner` | [`PlannerConfig`] | Algorithm 1's settings beside the five tuned parameters |
//! | `mpc` | [`crate::convex_mpc::MpcConfig`] | eq. (2): horizon, weights, force bounds, friction |
//! | `swing` | [`crate::leg_control::SwingGains`] | eq. (1)'s gains |
//! | `slip` | [`crate::slip::SlipConfig`] | the friction estimate on slippery ground |
//! | `schedule` | `mpc_period_s` | how often the MPC solves |
//! | `filter` | [`KfConfig`] | the Kalman filter (runs on the filter only) |
//!
//! A key that does not exist is refused by name (serde's `deny_unknown_fields` on every struct),
//! as is a value of the wrong type or out of its range.

use crate::estimator::KfConfig;
use crate::locomotion::ControllerConfig;
use crate::planner::PlannerConfig;
use toml::Value;

/// The tables of the settings tree, in the order `eemp config show` prints them.
pub const TABLES: [&str; 6] = ["planner", "mpc", "swing", "slip", "schedule", "filter"];

/// Keys [`ControllerSettings::scaled`] leaves as they are, though they have a unit:
/// - how often the MPC solves is a control rate of the computer, not a property of the robot's
///   motion (a slower rate lets a trunk light in roll for its size oscillate off its feet);
/// - the filter's foot height is already the robot's own foot radius (`StateSource::kf`):
///   scaling it again would put the feet, and so the filter's trunk, at the wrong height.
pub const UNSCALED_KEYS: [&str; 2] = ["schedule.mpc_period_s", "filter.foot_height_m"];

/// The settings a run controls itself with: planner, controller, and (on the filter) the
/// filter's.
#[derive(Clone, Debug, PartialEq)]
pub struct ControllerSettings {
    pub planner: PlannerConfig,
    pub controller: ControllerConfig,
    /// `None` on ground truth.
    pub filter: Option<KfConfig>,
}

fn to_value<T: serde::Serialize>(x: &T) -> Value {
    Value::try_from(x).expect("a config struct serialises to TOML")
}

impl ControllerSettings {
    /// The settings as a TOML tree (the tables of [`TABLES`]).
    pub fn to_tree(&self) -> toml::Table {
        let mut t = toml::Table::new();
        t.insert("planner".into(), to_value(&self.planner));
        t.insert("mpc".into(), to_value(&self.controller.mpc));
        t.insert("swing".into(), to_value(&self.controller.swing));
        t.insert("slip".into(), to_value(&self.controller.slip));
        let mut schedule = toml::Table::new();
        schedule.insert(
            "mpc_period_s".into(),
            Value::Float(self.controller.mpc_period_s),
        );
        t.insert("schedule".into(), Value::Table(schedule));
        if let Some(kf) = &self.filter {
            t.insert("filter".into(), to_value(kf));
        }
        t
    }

    /// The settings of a tree made by [`ControllerSettings::to_tree`] and edited; `origin`
    /// names where the edits came from in errors.
    pub fn from_tree(tree: &toml::Table, origin: &str) -> Result<Self, String> {
        fn part<T: serde::de::DeserializeOwned>(
            tree: &toml::Table,
            name: &str,
            origin: &str,
        ) -> Result<T, String> {
            let v = tree
                .get(name)
                .cloned()
                .unwrap_or(Value::Table(Default::default()));
            v.try_into()
                .map_err(|e: toml::de::Error| format!("{origin}: [{name}]: {}", e.message()))
        }
        let mut controller = ControllerConfig {
            mpc: part(tree, "mpc", origin)?,
            swing: part(tree, "swing", origin)?,
            slip: part(tree, "slip", origin)?,
            ..ControllerConfig::default()
        };
        #[derive(serde::Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Schedule {
            mpc_period_s: f64,
        }
        let schedule: Schedule = part(tree, "schedule", origin)?;
        controller.mpc_period_s = schedule.mpc_period_s;
        let s = ControllerSettings {
            planner: part(tree, "planner", origin)?,
            controller,
            filter: match tree.get("filter") {
                Some(_) => Some(part(tree, "filter", origin)?),
                None => None,
            },
        };
        s.planner.validate().map_err(|e| format!("{origin}: {e}"))?;
        s.controller
            .validate()
            .map_err(|e| format!("{origin}: {e}"))?;
        if let Some(kf) = &s.filter {
            kf.validate()
                // The filter's own messages name its keys as the training config's `[kf]` does.
                .map_err(|e| {
                    format!("{origin}: {}", e.to_string().replacen("kf.", "filter.", 1))
                })?;
        }
        Ok(s)
    }

    /// These settings scaled to a robot of `scale` ([`crate::robot::RobotScale`]): every key
    /// of [`crate::settings_keys::KEYS`] with a physical unit, multiplied by its unit's factor
    /// (a key left unset stays unset).
    pub fn scaled(&self, scale: &crate::robot::RobotScale) -> Result<Self, String> {
        let mut tree = self.to_tree();
        for doc in crate::settings_keys::KEYS {
            if UNSCALED_KEYS.contains(&doc.key) {
                continue;
            }
            let Some(f) = scale.factor(doc.unit) else {
                continue;
            };
            let mut at: Option<&mut Value> = None;
            for (i, part) in doc.key.split('.').enumerate() {
                at = match (i, at) {
                    (0, _) => tree.get_mut(part),
                    (_, Some(Value::Table(t))) => t.get_mut(part),
                    _ => None,
                };
            }
            match at {
                Some(Value::Float(x)) => *x *= f,
                Some(Value::Array(items)) => {
                    for v in items {
                        if let Value::Float(x) = v {
                            *x *= f;
                        }
                    }
                }
                _ => {}
            }
        }
        ControllerSettings::from_tree(&tree, "the settings scaled to the robot")
    }

    /// These settings with each `key=value` of `sets` applied in order (dotted keys into the
    /// tree, a value in TOML syntax; a bare word is read as a string). Errors name the
    /// assignment, the key and what is allowed.
    pub fn with_sets(&self, sets: &[String]) -> Result<Self, String> {
        if sets.is_empty() {
            return Ok(self.clone());
        }
        let mut tree = self.to_tree();
        for s in sets {
            set_in_tree(&mut tree, s)?;
        }
        let origin = format!("--set {}", sets.join(" --set "));
        ControllerSettings::from_tree(&tree, &origin)
    }
}

/// The key of a `key=value` assignment, trimmed (the whole text where there is no `=`).
pub fn key_of(assignment: &str) -> &str {
    assignment
        .split_once('=')
        .map_or(assignment, |(k, _)| k)
        .trim()
}

/// Parses `key=value` and writes it into `tree`.
pub fn set_in_tree(tree: &mut toml::Table, assignment: &str) -> Result<(), String> {
    let Some((key, raw)) = assignment.split_once('=') else {
        return Err(format!(
            "--set {assignment}: expected KEY=VALUE (e.g. mpc.horizon=12)"
        ));
    };
    let (key, raw) = (key.trim(), raw.trim());
    let path: Vec<&str> = key.split('.').collect();
    if path.len() < 2 || path.iter().any(|p| p.is_empty()) {
        return Err(format!(
            "--set {assignment}: the key must name a table and a field (tables: {})",
            TABLES.join(", ")
        ));
    }
    if key == "planner.gait" {
        return Err(format!(
            "--set {assignment}: the gait is what a run asks for, not a setting: use --gait"
        ));
    }
    let value = parse_value(raw);
    let mut at = &mut *tree;
    for (i, seg) in path[..path.len() - 1].iter().enumerate() {
        let here = path[..i].join(".");
        let known: Vec<String> = at.keys().cloned().collect();
        match at.get_mut(*seg) {
            Some(Value::Table(t)) => at = t,
            Some(_) => {
                return Err(format!(
                    "--set {assignment}: {} is a value, not a table",
                    path[..=i].join(".")
                ))
            }
            None => {
                let place = if here.is_empty() {
                    "the settings tree".to_string()
                } else {
                    here
                };
                let hint = if i == 0 && *seg == "filter" {
                    " (the filter's settings exist on the kf estimator)"
                } else {
                    ""
                };
                return Err(format!(
                    "--set {assignment}: unknown key {}: {place} has {}{hint}",
                    path[..=i].join("."),
                    known.join(", ")
                ));
            }
        }
    }
    let last = path[path.len() - 1];
    let value = match (at.get(last), value) {
        // An integer where the field holds a float is that float.
        (Some(Value::Float(_)), Value::Integer(n)) => Value::Float(n as f64),
        (Some(old), v) if std::mem::discriminant(old) != std::mem::discriminant(&v) => {
            return Err(format!(
                "--set {assignment}: {key} holds {} ({}), not {}",
                type_name(old),
                old,
                type_name(&v)
            ))
        }
        (_, v) => v,
    };
    // A key not in the tree is either an unset option (accepted by its struct) or a typo
    // (refused by its struct's deny_unknown_fields when the tree is read back).
    at.insert(last.to_string(), value);
    Ok(())
}

fn parse_value(raw: &str) -> Value {
    match toml::from_str::<toml::Table>(&format!("v = {raw}")) {
        Ok(mut t) => t.remove("v").expect("parsed v"),
        Err(_) => Value::String(raw.to_string()),
    }
}

fn type_name(v: &Value) -> &'static str {
    match v {
        Value::String(_) => "a string",
        Value::Integer(_) => "an integer",
        Value::Float(_) => "a number",
        Value::Boolean(_) => "true or false",
        Value::Datetime(_) => "a date",
        Value::Array(_) => "a list",
        Value::Table(_) => "a table",
    }
}

/// Every leaf key of a tree, dotted, with its value (what `eemp config show` lists and the
/// tests enumerate).
pub fn leaves(tree: &toml::Table) -> Vec<(String, Value)> {
    fn walk(prefix: &str, t: &toml::Table, out: &mut Vec<(String, Value)>) {
        for (k, v) in t {
            let key = if prefix.is_empty() {
                k.clone()
            } else {
                format!("{prefix}.{k}")
            };
            match v {
                Value::Table(sub) => walk(&key, sub, out),
                v => out.push((key, v.clone())),
            }
        }
    }
    let mut out = Vec::new();
    walk("", tree, &mut out);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::planner::Gait;

    fn defaults() -> ControllerSettings {
        ControllerSettings {
            planner: PlannerConfig {
                gait: Gait::Free,
                ..Default::default()
            },
            controller: ControllerConfig::default(),
            filter: Some(KfConfig::default()),
        }
    }

    #[test]
    fn every_leaf_is_reachable_by_set_and_round_trips() {
        let s = defaults();
        let tree = s.to_tree();
        let leaves = leaves(&tree);
        assert!(leaves.len() > 40, "{} keys", leaves.len());
        for (key, value) in leaves {
            if key == "planner.gait" {
                continue;
            }
            let same = s.with_sets(&[format!("{key}={value}")]).unwrap();
            assert_eq!(same, s, "{key}={value}");
        }
    }

    #[test]
    fn a_set_changes_its_field_and_only_it() {
        let s = defaults();
        let t = s
            .with_sets(&["mpc.horizon=12".into(), "schedule.mpc_period_s=0.01".into()])
            .unwrap();
        assert_eq!(t.controller.mpc.horizon, 12);
        assert_eq!(t.controller.mpc_period_s, 0.01);
        let mut back = t.clone();
        back.controller.mpc.horizon = s.controller.mpc.horizon;
        back.controller.mpc_period_s = s.controller.mpc_period_s;
        assert_eq!(back, s);
        // An option that is unset by default can be set.
        let u = s.with_sets(&["slip.initial_friction=0.4".into()]).unwrap();
        assert_eq!(u.controller.slip.initial_friction, Some(0.4));
    }

    #[test]
    fn typos_types_and_ranges_are_refused_by_name() {
        let s = defaults();
        for (set, needles) in [
            ("mpc.horizn=12", &["horizn", "--set mpc.horizn=12"][..]),
            ("mcp.horizon=12", &["unknown key mcp", "mpc, planner"][..]),
            ("mpc.horizon", &["KEY=VALUE"][..]),
            ("horizon=3", &["table and a field"][..]),
            ("mpc.horizon=true", &["mpc.horizon holds an integer"][..]),
            ("schedule.mpc_period_s=5.0", &["mpc_period_s", "0.1"][..]),
            ("planner.gait=trot", &["--gait"][..]),
        ] {
            let err = s.with_sets(&[set.to_string()]).unwrap_err();
            for n in needles {
                assert!(err.contains(n), "{set}: '{n}' not in: {err}");
            }
        }
        let ground_truth = ControllerSettings {
            filter: None,
            ..defaults()
        };
        let err = ground_truth
            .with_sets(&["filter.leg_outlier_mps=0.5".into()])
            .unwrap_err();
        assert!(err.contains("kf estimator"), "{err}");
    }
}
