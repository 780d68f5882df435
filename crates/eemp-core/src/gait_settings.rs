//! Each gait's controller settings as data: `settings/<gait>.toml`, compiled in. A file holds
//! the gait's values where they differ from the config structs' own defaults, as a partial
//! settings tree (`[planner]`, `[slip]`, …, the tables of the `settings` module); the structs
//! read their per-gait defaults from it (`SlipConfig::default_for`,
//! `PlannerConfig::ellipse_friction_factor_in_force`), so a gait's rules are
//! one file to read and diff, not branches in code.
//!
//! The module names gaits by their names and imports nothing else of the crate, so every layer
//! may read it.

use serde::{de::DeserializeOwned, Serialize};
use std::sync::OnceLock;

/// The gait files: (gait, path from the repository root, text).
pub const GAIT_FILES: [(&str, &str, &str); 3] = [
    (
        "trot",
        "settings/trot.toml",
        include_str!("../../../settings/trot.toml"),
    ),
    (
        "walk",
        "settings/walk.toml",
        include_str!("../../../settings/walk.toml"),
    ),
    (
        "free",
        "settings/free.toml",
        include_str!("../../../settings/free.toml"),
    ),
];

fn parsed() -> &'static [toml::Table; 3] {
    static PARSED: OnceLock<[toml::Table; 3]> = OnceLock::new();
    PARSED.get_or_init(|| {
        GAIT_FILES.map(|(_, path, text)| {
            // Compiled in and parsed by a test: a failure here is a build of a broken file.
            toml::from_str(text).unwrap_or_else(|e| panic!("{path}: {e}"))
        })
    })
}

/// The gait's file: its path and its tree. Panics on a gait without a file (every `Gait` has
/// one; a test checks).
pub fn gait_file(gait: &str) -> (&'static str, &'static toml::Table) {
    let i = GAIT_FILES
        .iter()
        .position(|(g, _, _)| *g == gait)
        .unwrap_or_else(|| panic!("no settings file for gait '{gait}'"));
    (GAIT_FILES[i].1, &parsed()[i])
}

/// Writes every leaf of `over` into `into` (tables merged key by key).
pub fn merge(into: &mut toml::Table, over: &toml::Table) {
    for (k, v) in over {
        match (into.get_mut(k), v) {
            (Some(toml::Value::Table(a)), toml::Value::Table(b)) => merge(a, b),
            _ => {
                into.insert(k.clone(), v.clone());
            }
        }
    }
}

/// `base` with the gait file's `[table]` written over it.
pub fn with_gait_table<T: Serialize + DeserializeOwned + Clone>(
    base: &T,
    gait: &str,
    table: &str,
) -> T {
    let (path, file) = gait_file(gait);
    let Some(over) = file.get(table).and_then(|t| t.as_table()) else {
        return base.clone();
    };
    let mut tree = toml::Table::try_from(base).expect("a config struct serialises to TOML");
    merge(&mut tree, over);
    toml::Value::Table(tree)
        .try_into()
        .unwrap_or_else(|e: toml::de::Error| panic!("{path}: [{table}]: {}", e.message()))
}

/// A number the gait's file must set (`table.key`); panics naming the file where it does not
/// (a test checks every one the code reads).
pub fn gait_number(gait: &str, table: &str, key: &str) -> f64 {
    let (path, file) = gait_file(gait);
    file.get(table)
        .and_then(|t| t.get(key))
        .and_then(|v| v.as_float().or_else(|| v.as_integer().map(|i| i as f64)))
        .unwrap_or_else(|| panic!("{path} does not set {table}.{key}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_gait_has_a_file_that_parses_and_sets_what_the_code_reads() {
        for g in ["trot", "walk", "free"] {
            let (path, t) = gait_file(g);
            assert!(path.ends_with(&format!("{g}.toml")));
            assert!(t.contains_key("planner"), "{path}");
            for key in ["ellipse_friction_factor", "touchdown_friction_factor"] {
                let _ = gait_number(g, "planner", key);
            }
        }
    }

    #[test]
    fn a_gait_file_holds_only_keys_the_code_reads_from_it() {
        // `[slip]` is merged whole (`SlipConfig::default_for`); of `[planner]` the two friction
        // factors are read (`PlannerConfig::*_in_force`). A key anywhere else would be ignored.
        for (gait, path, _) in GAIT_FILES {
            let (_, t) = gait_file(gait);
            for (table, v) in t {
                let keys: Vec<&String> = v.as_table().expect("tables").keys().collect();
                let read = match table.as_str() {
                    "slip" => true,
                    "planner" => keys.iter().all(|k| {
                        ["ellipse_friction_factor", "touchdown_friction_factor"]
                            .contains(&k.as_str())
                    }),
                    _ => false,
                };
                assert!(read, "{path}: [{table}] {keys:?} is not read by the code");
            }
        }
    }

    #[test]
    fn a_gait_table_overrides_only_its_keys() {
        let mut a: toml::Table = toml::from_str("[x]\na = 1\nb = 2\n[y]\nc = 3").unwrap();
        let b: toml::Table = toml::from_str("[x]\nb = 5").unwrap();
        merge(&mut a, &b);
        assert_eq!(a.to_string(), "[x]\na = 1\nb = 5\n\n[y]\nc = 3\n");
    }
}
