//! The reproduction pipeline (`reproduce.toml`, `eemp reproduce`): the study as ordered stages,
//! each a list of `eemp` commands with the files it reads and writes, and the manifests that say
//! which shipped artifact still matches its inputs.
//!
//! Each stage is of the *study* (what the paper's page, the comparisons and the defaults use:
//! `eemp reproduce` runs these) or an *experiment* (earlier variants, ablations: on request). The
//! study is closed: no study stage reads what an experiment makes, so the study stages alone
//! regenerate every study artifact from the pipeline's sources.
//!
//! A *root* is a folder laid out as the repository (`tables/`, `policies/`, `reports/`, the
//! configs): the repository itself, or the `--out` of a reproduction, which starts with a copy of
//! the pipeline's sources. Every path of a stage is relative to the root; commands run in it.
//!
//! Kept in Rust rather than Snakemake or DVC: every step is already an `eemp` command that
//! resumes itself, so the pipeline only orders them and hashes files, and a user needs nothing
//! beyond the one binary (no Python environment on the robot's computer or the cluster).

use serde::{Deserialize, Serialize};
use sha2::{Digest, Sha256};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The pipeline file.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Pipeline {
    /// Files and folders a new root gets copied from the repository before any stage runs (the
    /// robots, scenarios, sweep, suite and training configs): the inputs no stage makes.
    pub sources: Vec<String>,
    #[serde(rename = "stage")]
    pub stages: Vec<Stage>,
}

/// One stage: what it is for, what it reads and writes, and its steps.
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stage {
    pub name: String,
    /// One line for the listing and the report.
    pub about: String,
    /// Files or folders whose content keys the stage (configs, and artifacts of earlier stages).
    pub inputs: Vec<String>,
    /// Source folders whose version the manifest records ("the code that made it").
    #[serde(default)]
    pub code: Vec<String>,
    /// The artifacts the stage writes (files or folders).
    pub outputs: Vec<String>,
    /// The wall time measured for the full stage on 2 cores, for the listing [min].
    #[serde(default)]
    pub minutes_2_cores: Option<f64>,
    /// `"study"` (the default) or `"experiment"` (see [`StageKind`]); checked by
    /// [`Pipeline::load`].
    #[serde(default = "default_kind")]
    pub kind: String,
    /// Inputs an experiment makes that this study stage reads as shipped: a fine-tune's parent
    /// checkpoint, an earlier variant compared beside the current one. The study regenerates
    /// from the sources and these files (pinned by the manifest like any input); `--experiments`
    /// re-makes them too. Each must be one of `inputs`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub shipped_inputs: Vec<String>,
    #[serde(rename = "step")]
    pub steps: Vec<Step>,
}

fn default_kind() -> String {
    StageKind::Study.name().to_string()
}

/// Whether a stage belongs to the study or is an experiment.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum StageKind {
    /// Makes what the paper's page (`reports/paper` and the reports it reads), the comparisons or
    /// the defaults (the per-robot tables walks load) use, or what such a stage reads: run by
    /// `eemp reproduce`.
    Study,
    /// An earlier variant or an ablation that no study stage reads: run on request
    /// (`--experiments`, or `--stage NAME`).
    Experiment,
}

impl StageKind {
    pub const ALL: [StageKind; 2] = [StageKind::Study, StageKind::Experiment];

    pub fn name(self) -> &'static str {
        match self {
            StageKind::Study => "study",
            StageKind::Experiment => "experiment",
        }
    }

    pub fn parse(s: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == s)
    }
}

/// One step: an `eemp` command line or a copy. `{work}` in an argument is the stage's scratch
/// folder (`out/reproduce/<stage>` in the root).
#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Step {
    /// `eemp` arguments, e.g. `["sweep", "--config", "sweeps/paper.toml", "--out", "{work}"]`.
    #[serde(default)]
    pub run: Option<Vec<String>>,
    /// The arguments under `--quick` (default: `run`'s).
    #[serde(default)]
    pub quick: Option<Vec<String>>,
    /// `[from, to]`: copy a file or folder (after the commands before it).
    #[serde(default)]
    pub copy: Option<[String; 2]>,
    /// Under `--shard K/N` this step runs with `--shard K/N` appended and `{work}` becomes
    /// `{work}/shard-K-of-N`; the stage's other steps wait for the merge.
    #[serde(default)]
    pub shard: bool,
}

/// What a step does, with `{work}` resolved.
#[derive(Debug, Clone, PartialEq)]
pub enum Action {
    Eemp(Vec<String>),
    Copy { from: String, to: String },
}

#[derive(Debug, thiserror::Error)]
pub enum PipelineError {
    #[error("{path}: {message}")]
    File { path: PathBuf, message: String },
    #[error("unknown stage '{name}' (stages: {known})")]
    UnknownStage { name: String, known: String },
    #[error("{0}")]
    Invalid(String),
}

fn file_error(path: &Path, message: impl ToString) -> PipelineError {
    PipelineError::File {
        path: path.to_path_buf(),
        message: message.to_string(),
    }
}

impl Pipeline {
    pub fn load(path: &Path) -> Result<Self, PipelineError> {
        let text = std::fs::read_to_string(path).map_err(|e| file_error(path, e))?;
        let p: Pipeline = toml::from_str(&text).map_err(|e| file_error(path, e))?;
        p.validate().map_err(|m| file_error(path, m))?;
        Ok(p)
    }

    fn validate(&self) -> Result<(), String> {
        let mut seen = std::collections::BTreeSet::new();
        let mut made: BTreeMap<&str, &str> = BTreeMap::new();
        for s in &self.stages {
            if !seen.insert(s.name.as_str()) {
                return Err(format!("stage '{}' is defined twice", s.name));
            }
            if s.name.is_empty()
                || !s
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-')
            {
                return Err(format!(
                    "stage name '{}': letters, digits and '-' only",
                    s.name
                ));
            }
            if s.steps.is_empty() {
                return Err(format!("stage '{}' has no step", s.name));
            }
            for st in &s.steps {
                match (&st.run, &st.copy) {
                    (Some(r), None) if !r.is_empty() => {}
                    (None, Some(_)) if st.quick.is_none() && !st.shard => {}
                    _ => {
                        return Err(format!(
                            "stage '{}': a step is either run = [eemp arguments] (with optional \
                             quick, shard) or copy = [from, to]",
                            s.name
                        ))
                    }
                }
            }
            if StageKind::parse(&s.kind).is_none() {
                return Err(format!(
                    "stage '{}': kind '{}' is not one of {}",
                    s.name,
                    s.kind,
                    StageKind::ALL.map(StageKind::name).join(", ")
                ));
            }
            for p in s.inputs.iter().chain(&s.outputs).chain(&s.code) {
                check_relative(p).map_err(|m| format!("stage '{}': {m}", s.name))?;
            }
            // An input made by a later stage would be read before it is written.
            for i in &s.inputs {
                if self
                    .stages
                    .iter()
                    .skip_while(|t| t.name != s.name)
                    .any(|t| t.outputs.iter().any(|o| o == i))
                {
                    return Err(format!(
                        "stage '{}' reads {i}, which it or a later stage writes",
                        s.name
                    ));
                }
            }
            for o in &s.outputs {
                if let Some(other) = made.insert(o, &s.name) {
                    return Err(format!(
                        "{o} is written by stages '{other}' and '{}'",
                        s.name
                    ));
                }
            }
        }
        for p in &self.sources {
            check_relative(p)?;
        }
        // The study is closed: running its stages alone regenerates every study artifact from
        // the sources and the shipped checkpoints it names.
        for s in &self.stages {
            if let Some(i) = s.shipped_inputs.iter().find(|i| !s.inputs.contains(i)) {
                return Err(format!(
                    "stage '{}': shipped input {i} is not one of its inputs",
                    s.name
                ));
            }
        }
        for s in self.stages.iter().filter(|s| s.is_study()) {
            for i in s.inputs.iter().filter(|i| !s.shipped_inputs.contains(i)) {
                if let Some(m) = self.maker_of(i).filter(|m| !m.is_study()) {
                    return Err(format!(
                        "stage '{}' is of the study but reads {i}, which the experiment '{}' \
                         makes (mark that stage kind = \"study\", this one an experiment, or \
                         name the file in its shipped_inputs)",
                        s.name, m.name
                    ));
                }
            }
        }
        Ok(())
    }

    pub fn stage(&self, name: &str) -> Result<&Stage, PipelineError> {
        self.stages
            .iter()
            .find(|s| s.name == name)
            .ok_or_else(|| PipelineError::UnknownStage {
                name: name.to_string(),
                known: self
                    .stages
                    .iter()
                    .map(|s| s.name.as_str())
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// The stages named, in pipeline order; when `names` is empty, the study's stages, and the
    /// experiments too with `experiments`.
    pub fn select(
        &self,
        names: &[String],
        experiments: bool,
    ) -> Result<Vec<&Stage>, PipelineError> {
        for n in names {
            self.stage(n)?;
        }
        Ok(self
            .stages
            .iter()
            .filter(|s| {
                if names.is_empty() {
                    experiments || s.is_study()
                } else {
                    names.iter().any(|n| n == &s.name)
                }
            })
            .collect())
    }

    /// The sum of `minutes_2_cores` over the stages of the study (`experiments = false`) or over
    /// all of them [min].
    pub fn minutes_2_cores(&self, experiments: bool) -> f64 {
        self.stages
            .iter()
            .filter(|s| experiments || s.is_study())
            .filter_map(|s| s.minutes_2_cores)
            .sum()
    }

    /// The stage that writes `path`, if any.
    pub fn maker_of(&self, path: &str) -> Option<&Stage> {
        self.stages
            .iter()
            .find(|s| s.outputs.iter().any(|o| o == path))
    }
}

fn check_relative(p: &str) -> Result<(), String> {
    let path = Path::new(p);
    if p.is_empty()
        || path.is_absolute()
        || path
            .components()
            .any(|c| matches!(c, std::path::Component::ParentDir))
    {
        return Err(format!(
            "path '{p}' must be relative to the root and stay inside it"
        ));
    }
    Ok(())
}

impl Stage {
    /// The stage's kind (an unknown one, refused by [`Pipeline::load`], reads as the study).
    pub fn kind(&self) -> StageKind {
        StageKind::parse(&self.kind).unwrap_or(StageKind::Study)
    }

    pub fn is_study(&self) -> bool {
        self.kind() == StageKind::Study
    }

    /// The stage's scratch folder, relative to the root.
    pub fn work_dir(&self) -> String {
        format!("out/reproduce/{}", self.name)
    }

    /// The scratch folder of shard `k` of `n`, or the stage's own: beside it, not inside, so
    /// that a step copying `{work}` into a report never takes the shards along.
    pub fn work_dir_of(&self, shard: Option<(usize, usize)>) -> String {
        match shard {
            Some((k, n)) => format!("{}.shard-{k}-of-{n}", self.work_dir()),
            None => self.work_dir(),
        }
    }

    /// The actions of a full (`quick = false`) or quick run, or of shard `k` of `n` (only the
    /// steps marked `shard`).
    pub fn actions(&self, quick: bool, shard: Option<(usize, usize)>) -> Vec<Action> {
        let work = self.work_dir_of(shard);
        let sub = |a: &String| a.replace("{work}", &work);
        self.steps
            .iter()
            .filter(|s| shard.is_none() || s.shard)
            .map(|s| match (&s.run, &s.copy) {
                (Some(run), _) => {
                    let args = if quick {
                        s.quick.as_ref().unwrap_or(run)
                    } else {
                        run
                    };
                    let mut v: Vec<String> = args.iter().map(sub).collect();
                    if let Some((k, n)) = shard {
                        v.push("--shard".into());
                        v.push(format!("{k}/{n}"));
                    }
                    Action::Eemp(v)
                }
                (None, Some([from, to])) => Action::Copy {
                    from: sub(from),
                    to: sub(to),
                },
                (None, None) => unreachable!("validated"),
            })
            .collect()
    }

    pub fn shardable(&self) -> bool {
        self.steps.iter().any(|s| s.shard)
    }

    /// The folders the merges of [`Stage::merge_actions`] read (each shard step's `--out`).
    pub fn shard_outputs(&self, quick: bool, n: usize) -> Vec<String> {
        (1..=n)
            .flat_map(|k| self.actions(quick, Some((k, n))))
            .filter_map(|a| a.out_dir())
            .collect()
    }

    /// What gathers the `n` shard folders of each shardable step into the folder the full step
    /// writes (its `--out`), so that the stage then only finishes: `eemp sweep merge` for a
    /// sweep, the suite's own command with `--merge-from` for a suite.
    pub fn merge_actions(&self, quick: bool, n: usize) -> Vec<Action> {
        let full = self.actions(quick, None);
        let shards: Vec<Vec<Action>> = (1..=n).map(|k| self.actions(quick, Some((k, n)))).collect();
        let sharded: Vec<&Action> = self
            .steps
            .iter()
            .zip(&full)
            .filter(|(s, _)| s.shard)
            .map(|(_, a)| a)
            .collect();
        let mut out = Vec::new();
        for (i, action) in sharded.into_iter().enumerate() {
            let (Action::Eemp(args), Some(to)) = (action, action.out_dir()) else {
                continue;
            };
            let from: Vec<String> = shards.iter().filter_map(|s| s.get(i)?.out_dir()).collect();
            let merge = if args.first().map(String::as_str) == Some("sweep") {
                let mut v = vec!["sweep".to_string(), "merge".to_string()];
                v.extend(from);
                v.extend(["--out".to_string(), to]);
                v
            } else {
                let mut v = args.clone();
                v.push("--merge-from".into());
                v.extend(from);
                v
            };
            out.push(Action::Eemp(merge));
        }
        out
    }
}

impl Action {
    /// The folder an `eemp` step writes (its `--out`).
    pub fn out_dir(&self) -> Option<String> {
        match self {
            Action::Eemp(args) => {
                let i = args.iter().position(|a| a == "--out")?;
                args.get(i + 1).cloned()
            }
            Action::Copy { .. } => None,
        }
    }

    /// As a user would type it.
    pub fn display(&self) -> String {
        match self {
            Action::Eemp(args) => {
                let quoted: Vec<String> = args
                    .iter()
                    .map(|a| {
                        if a.is_empty() || a.contains(|c: char| c.is_whitespace() || c == '\'') {
                            format!("'{}'", a.replace('\'', "'\\''"))
                        } else {
                            a.clone()
                        }
                    })
                    .collect();
                format!("eemp {}", quoted.join(" "))
            }
            Action::Copy { from, to } => format!("cp -r {from} {to}"),
        }
    }
}

/// `--shard K/N` (1-based K).
pub fn parse_shard(s: &str) -> Result<(usize, usize), String> {
    let bad = || format!("--shard '{s}': expected K/N with 1 ≤ K ≤ N, e.g. 3/8");
    let (k, n) = s.split_once('/').ok_or_else(bad)?;
    let k: usize = k.trim().parse().map_err(|_| bad())?;
    let n: usize = n.trim().parse().map_err(|_| bad())?;
    if k == 0 || n == 0 || k > n {
        return Err(bad());
    }
    Ok((k, n))
}

/// Files a folder's hash leaves out: what no two runs share (a suite's per-run wall times).
pub const UNHASHED_FILES: &[&str] = &["timing.csv"];

/// The SHA-256 of a file, or of a folder: of its files' relative paths and hashes, sorted, so
/// the same content gives the same hash wherever it lies (less [`UNHASHED_FILES`]). `None` when
/// nothing is there.
pub fn hash_path(path: &Path) -> std::io::Result<Option<String>> {
    if path.is_file() {
        let bytes = std::fs::read(path)?;
        return Ok(Some(hex(&Sha256::digest(&bytes))));
    }
    if !path.is_dir() {
        return Ok(None);
    }
    let mut files = Vec::new();
    collect_files(path, path, &mut files)?;
    files.sort();
    let mut h = Sha256::new();
    for rel in files {
        let bytes = std::fs::read(path.join(&rel))?;
        h.update(rel.as_bytes());
        h.update(b"\0");
        h.update(hex(&Sha256::digest(&bytes)).as_bytes());
        h.update(b"\n");
    }
    Ok(Some(hex(&h.finalize())))
}

fn collect_files(base: &Path, dir: &Path, out: &mut Vec<String>) -> std::io::Result<()> {
    for e in std::fs::read_dir(dir)? {
        let e = e?;
        let p = e.path();
        if p.is_dir() {
            collect_files(base, &p, out)?;
        } else if !UNHASHED_FILES.contains(&e.file_name().to_string_lossy().as_ref()) {
            let rel = p.strip_prefix(base).expect("inside").to_string_lossy();
            out.push(rel.replace('\\', "/"));
        }
    }
    Ok(())
}

fn hex(bytes: &[u8]) -> String {
    bytes.iter().map(|b| format!("{b:02x}")).collect()
}

/// What made a stage's artifacts: written by `eemp reproduce` after a stage finishes, in
/// `manifests/<stage>.toml` of the root.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    pub stage: String,
    /// `eemp reproduce` (the stage ran) or `recorded` (`eemp reproduce --record`: the inputs of
    /// artifacts made earlier by the same commands by hand; the code that made them unknown).
    pub made_by: String,
    /// Made at `--quick` scale (a check of the pipeline, not a result).
    pub quick: bool,
    /// `eemp`'s version (the workspace's).
    pub eemp_version: String,
    /// The commands, as typed.
    pub commands: Vec<String>,
    /// Wall time of the stage [s] (absent when recorded).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wall_s: Option<f64>,
    /// SHA-256 of each input (see [`hash_path`]).
    pub inputs: BTreeMap<String, String>,
    /// SHA-256 of each code folder at the time (empty when recorded).
    #[serde(default)]
    pub code: BTreeMap<String, String>,
    /// SHA-256 of each output as written.
    pub outputs: BTreeMap<String, String>,
}

impl Manifest {
    pub fn path(root: &Path, stage: &str) -> PathBuf {
        root.join("manifests").join(format!("{stage}.toml"))
    }

    /// `Ok(None)` when there is none; an error names a manifest that does not parse.
    pub fn load(root: &Path, stage: &str) -> Result<Option<Manifest>, PipelineError> {
        let path = Self::path(root, stage);
        if !path.exists() {
            return Ok(None);
        }
        let text = std::fs::read_to_string(&path).map_err(|e| file_error(&path, e))?;
        let m: Manifest =
            toml::from_str(&text).map_err(|e| file_error(&path, format!("not a manifest: {e}")))?;
        if m.stage != stage {
            return Err(file_error(
                &path,
                format!("is the manifest of stage '{}', not '{stage}'", m.stage),
            ));
        }
        Ok(Some(m))
    }

    pub fn save(&self, root: &Path) -> Result<(), PipelineError> {
        let path = Self::path(root, &self.stage);
        let text = format!(
            "# What made stage '{}'s artifacts (eemp reproduce; format: docs/reproduce.md).\n{}",
            self.stage,
            toml::to_string(self).expect("a manifest serialises")
        );
        std::fs::create_dir_all(path.parent().expect("has a parent"))
            .map_err(|e| file_error(&path, e))?;
        let tmp = path.with_extension("toml.tmp");
        std::fs::write(&tmp, text).map_err(|e| file_error(&tmp, e))?;
        std::fs::rename(&tmp, &path).map_err(|e| file_error(&path, e))
    }
}

/// Hashes of `paths` under `root` (`None` for a missing one).
pub fn hash_all(
    root: &Path,
    paths: &[String],
) -> Result<BTreeMap<String, Option<String>>, PipelineError> {
    paths
        .iter()
        .map(|p| {
            let full = root.join(p);
            hash_path(&full)
                .map(|h| (p.clone(), h))
                .map_err(|e| file_error(&full, e))
        })
        .collect()
}

/// Why a stage is not up to date (empty: it is).
#[derive(Debug, Clone, PartialEq)]
pub enum Staleness {
    NoManifest,
    Quick,
    InputChanged(String),
    InputMissing(String),
    OutputChanged(String),
    OutputMissing(String),
    StageChanged(String),
}

impl std::fmt::Display for Staleness {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Staleness::NoManifest => write!(f, "no manifest: not made by `eemp reproduce`"),
            Staleness::Quick => write!(f, "made at --quick scale"),
            Staleness::InputChanged(p) => write!(f, "input {p} changed since"),
            Staleness::InputMissing(p) => write!(f, "input {p} is missing"),
            Staleness::OutputChanged(p) => write!(f, "{p} differs from what the stage wrote"),
            Staleness::OutputMissing(p) => write!(f, "{p} is missing"),
            Staleness::StageChanged(what) => {
                write!(f, "the stage's {what} changed in the pipeline")
            }
        }
    }
}

/// A stage's state in a root: why it is stale, and the code folders changed since (a note:
/// most code changes do not change results; `--strict` counts them).
#[derive(Debug, Clone, PartialEq)]
pub struct StageCheck {
    pub stale: Vec<Staleness>,
    pub code_changed: Vec<String>,
    pub manifest: Option<Manifest>,
}

impl StageCheck {
    pub fn up_to_date(&self, strict: bool) -> bool {
        self.stale.is_empty() && (!strict || self.code_changed.is_empty())
    }
}

/// Compare a stage's manifest in `root` with its inputs and outputs there; code folders are
/// hashed in `code_root` (the repository).
pub fn check_stage(
    root: &Path,
    code_root: &Path,
    stage: &Stage,
    quick: bool,
) -> Result<StageCheck, PipelineError> {
    let manifest = Manifest::load(root, &stage.name)?;
    let mut stale = Vec::new();
    let mut code_changed = Vec::new();
    let Some(m) = &manifest else {
        return Ok(StageCheck {
            stale: vec![Staleness::NoManifest],
            code_changed,
            manifest,
        });
    };
    if m.quick != quick {
        stale.push(Staleness::Quick);
    }
    let listed = |v: &[String]| v.iter().cloned().collect::<std::collections::BTreeSet<_>>();
    if listed(&stage.inputs) != m.inputs.keys().cloned().collect() {
        stale.push(Staleness::StageChanged("inputs".into()));
    }
    if listed(&stage.outputs) != m.outputs.keys().cloned().collect() {
        stale.push(Staleness::StageChanged("outputs".into()));
    }
    for (p, h) in hash_all(root, &stage.inputs)? {
        match (h, m.inputs.get(&p)) {
            (None, _) => stale.push(Staleness::InputMissing(p)),
            (Some(h), Some(was)) if &h != was => stale.push(Staleness::InputChanged(p)),
            _ => {}
        }
    }
    for (p, h) in hash_all(root, &stage.outputs)? {
        match (h, m.outputs.get(&p)) {
            (None, _) => stale.push(Staleness::OutputMissing(p)),
            (Some(h), Some(was)) if &h != was => stale.push(Staleness::OutputChanged(p)),
            _ => {}
        }
    }
    if !m.code.is_empty() {
        for (p, h) in hash_all(code_root, &stage.code)? {
            if h.as_ref() != m.code.get(&p) {
                code_changed.push(p);
            }
        }
    }
    Ok(StageCheck {
        stale,
        code_changed,
        manifest,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    const PIPE: &str = r#"
sources = ["sweeps"]

[[stage]]
name = "sweep"
about = "a sweep"
inputs = ["sweeps/a.toml"]
code = ["src"]
outputs = ["tables/a.toml"]
[[stage.step]]
run = ["sweep", "--config", "sweeps/a.toml", "--out", "{work}"]
quick = ["sweep", "--config", "sweeps/smoke.toml", "--out", "{work}"]
shard = true
[[stage.step]]
run = ["sweep", "report", "{work}", "--tables-out", "tables"]

[[stage]]
name = "suite"
about = "a suite"
inputs = ["tables/a.toml"]
outputs = ["reports/a"]
[[stage.step]]
copy = ["{work}/x", "reports/a"]
"#;

    fn pipe() -> Pipeline {
        let p: Pipeline = toml::from_str(PIPE).unwrap();
        p.validate().unwrap();
        p
    }

    #[test]
    fn actions_resolve_work_quick_and_shards() {
        let p = pipe();
        let s = p.stage("sweep").unwrap();
        assert_eq!(
            s.actions(false, None)[0],
            Action::Eemp(
                [
                    "sweep",
                    "--config",
                    "sweeps/a.toml",
                    "--out",
                    "out/reproduce/sweep"
                ]
                .map(String::from)
                .to_vec()
            )
        );
        assert!(s.actions(true, None)[0]
            .display()
            .contains("sweeps/smoke.toml"));
        let sharded = s.actions(false, Some((2, 3)));
        assert_eq!(sharded.len(), 1, "the report waits for the merge");
        assert_eq!(
            sharded[0].display(),
            "eemp sweep --config sweeps/a.toml --out out/reproduce/sweep.shard-2-of-3 --shard 2/3"
        );
        assert!(s.shardable() && !p.stage("suite").unwrap().shardable());
        let merge: Vec<String> = s
            .merge_actions(false, 2)
            .iter()
            .map(Action::display)
            .collect();
        assert_eq!(
            merge,
            ["eemp sweep merge out/reproduce/sweep.shard-1-of-2 out/reproduce/sweep.shard-2-of-2 \
              --out out/reproduce/sweep"]
        );
    }

    #[test]
    fn a_suite_merges_its_shards_with_its_own_command() {
        let p: Pipeline = toml::from_str(
            r#"
sources = []

[[stage]]
name = "compare"
about = "x"
inputs = []
outputs = ["reports/c"]
[[stage.step]]
run = ["compare", "--config", "suites/c.toml", "--out", "{work}"]
shard = true
[[stage.step]]
copy = ["{work}", "reports/c"]
"#,
        )
        .unwrap();
        p.validate().unwrap();
        let merge: Vec<String> = p.stages[0]
            .merge_actions(false, 2)
            .iter()
            .map(Action::display)
            .collect();
        assert_eq!(
            merge,
            [
                "eemp compare --config suites/c.toml --out out/reproduce/compare --merge-from \
              out/reproduce/compare.shard-1-of-2 out/reproduce/compare.shard-2-of-2"
            ]
        );
    }

    #[test]
    fn bad_pipelines_and_names_are_refused_with_the_reason() {
        let err = pipe()
            .select(&["sweeps".into()], false)
            .unwrap_err()
            .to_string();
        assert_eq!(err, "unknown stage 'sweeps' (stages: sweep, suite)");
        for (from, to, says) in [
            (
                "inputs = [\"tables/a.toml\"]",
                "inputs = [\"reports/a\"]",
                "which it or a later stage writes",
            ),
            (
                "inputs = [\"tables/a.toml\"]\noutputs = [\"reports/a\"]",
                "inputs = []\noutputs = [\"tables/a.toml\"]",
                "is written by stages",
            ),
            ("name = \"suite\"", "name = \"sweep\"", "defined twice"),
            (
                "outputs = [\"reports/a\"]",
                "outputs = [\"../a\"]",
                "stay inside it",
            ),
            (
                "copy = [\"{work}/x\", \"reports/a\"]",
                "copy = [\"a\", \"b\"]\nshard = true",
                "a step is either",
            ),
        ] {
            let text = PIPE.replace(from, to);
            let p: Pipeline = toml::from_str(&text).unwrap();
            let e = p.validate().unwrap_err();
            assert!(e.contains(says), "{to}: {e}");
        }
        assert_eq!(parse_shard("2/3").unwrap(), (2, 3));
        for s in ["0/3", "4/3", "a/b", "3", "1/0"] {
            assert!(parse_shard(s).unwrap_err().contains("1 ≤ K ≤ N"), "{s}");
        }
    }

    #[test]
    fn a_stage_is_of_the_study_by_default_and_an_unknown_kind_is_refused_naming_it() {
        let p = pipe();
        assert!(p.stages.iter().all(Stage::is_study));
        let text = PIPE.replace("name = \"suite\"", "name = \"suite\"\nkind = \"ablation\"");
        let p: Pipeline = toml::from_str(&text).unwrap();
        assert_eq!(
            p.validate().unwrap_err(),
            "stage 'suite': kind 'ablation' is not one of study, experiment"
        );
        // An experiment is run on request; --stage runs it by name.
        let text = PIPE.replace(
            "name = \"suite\"",
            "name = \"suite\"\nkind = \"experiment\"",
        );
        let p: Pipeline = toml::from_str(&text).unwrap();
        p.validate().unwrap();
        assert_eq!(p.stage("suite").unwrap().kind(), StageKind::Experiment);
        let names = |v: Vec<&Stage>| v.iter().map(|s| s.name.clone()).collect::<Vec<_>>();
        assert_eq!(names(p.select(&[], false).unwrap()), ["sweep"]);
        assert_eq!(names(p.select(&[], true).unwrap()), ["sweep", "suite"]);
        assert_eq!(
            names(p.select(&["suite".into()], false).unwrap()),
            ["suite"]
        );
    }

    #[test]
    fn a_study_stage_reading_what_an_experiment_makes_is_refused() {
        let text = PIPE.replace(
            "name = \"sweep\"",
            "name = \"sweep\"\nkind = \"experiment\"\nminutes_2_cores = 2",
        );
        let p: Pipeline = toml::from_str(&text).unwrap();
        let e = p.validate().unwrap_err();
        assert!(
            e.starts_with(
                "stage 'suite' is of the study but reads tables/a.toml, which the experiment \
                 'sweep' makes"
            ),
            "{e}"
        );
        assert_eq!(
            (p.minutes_2_cores(false), p.minutes_2_cores(true)),
            (0.0, 2.0)
        );
    }

    #[test]
    fn folder_hashes_depend_on_content_and_names_not_on_place() {
        let d = tempfile::tempdir().unwrap();
        for base in ["a", "b"] {
            std::fs::create_dir_all(d.path().join(base).join("sub")).unwrap();
            std::fs::write(d.path().join(base).join("x.txt"), "x").unwrap();
            std::fs::write(d.path().join(base).join("sub/y.txt"), "y").unwrap();
        }
        let h = |p: &str| hash_path(&d.path().join(p)).unwrap();
        assert_eq!(h("a"), h("b"));
        // Wall times do not count: two reproductions differ in them and nowhere else.
        std::fs::write(d.path().join("b/timing.csv"), "run_id,wall_s\nr,1.5\n").unwrap();
        assert_eq!(h("a"), h("b"));
        // sha256("x"), as `printf x | sha256sum` gives it.
        assert_eq!(
            h("a/x.txt").unwrap(),
            "2d711642b726b04401627ca9fbac32f5c8530fb1903cc4db02258717921a4881"
        );
        std::fs::write(d.path().join("b/sub/y.txt"), "z").unwrap();
        assert_ne!(h("a"), h("b"));
        std::fs::rename(d.path().join("a/sub/y.txt"), d.path().join("a/sub/w.txt")).unwrap();
        assert_ne!(h("a"), hash_path(&d.path().join("b")).unwrap());
        assert_eq!(h("none"), None);
    }

    #[test]
    fn a_stage_is_stale_when_an_input_or_output_changes_and_notes_code() {
        let d = tempfile::tempdir().unwrap();
        let root = d.path();
        let w = |p: &str, s: &str| {
            std::fs::create_dir_all(root.join(p).parent().unwrap()).unwrap();
            std::fs::write(root.join(p), s).unwrap();
        };
        w("sweeps/a.toml", "grid");
        w("tables/a.toml", "table");
        w("src/lib.rs", "code");
        let p = pipe();
        let s = p.stage("sweep").unwrap();
        assert_eq!(
            check_stage(root, root, s, false).unwrap().stale,
            vec![Staleness::NoManifest]
        );
        let flat = |m: BTreeMap<String, Option<String>>| {
            m.into_iter().map(|(k, v)| (k, v.unwrap())).collect()
        };
        let m = Manifest {
            stage: "sweep".into(),
            made_by: "eemp reproduce".into(),
            quick: false,
            eemp_version: "0".into(),
            commands: vec![],
            wall_s: Some(1.0),
            inputs: flat(hash_all(root, &s.inputs).unwrap()),
            code: flat(hash_all(root, &s.code).unwrap()),
            outputs: flat(hash_all(root, &s.outputs).unwrap()),
        };
        m.save(root).unwrap();
        assert_eq!(Manifest::load(root, "sweep").unwrap().as_ref(), Some(&m));
        let c = check_stage(root, root, s, false).unwrap();
        assert!(c.up_to_date(true), "{c:?}");
        assert_eq!(
            check_stage(root, root, s, true).unwrap().stale,
            vec![Staleness::Quick]
        );
        w("src/lib.rs", "new code");
        let c = check_stage(root, root, s, false).unwrap();
        assert!(c.up_to_date(false) && !c.up_to_date(true));
        assert_eq!(c.code_changed, vec!["src".to_string()]);
        w("sweeps/a.toml", "grid edited");
        w("tables/a.toml", "table edited");
        assert_eq!(
            check_stage(root, root, s, false).unwrap().stale,
            vec![
                Staleness::InputChanged("sweeps/a.toml".into()),
                Staleness::OutputChanged("tables/a.toml".into())
            ]
        );
        std::fs::write(Manifest::path(root, "sweep"), "stage = 3").unwrap();
        let e = check_stage(root, root, s, false).unwrap_err().to_string();
        assert!(e.contains("sweep.toml: not a manifest"), "{e}");
    }
}
