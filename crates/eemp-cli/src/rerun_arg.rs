//! `--rerun FILE.rrd`, `--rerun-connect ADDR`, `--rerun-serve PORT`: a Rerun recording of the
//! run (issue 23), written by the `eemp-viz` recorder: through Python's rerun-sdk in every
//! build, or by Rerun's Rust SDK in a build with `--features rerun` (`make viewer`).

use eemp_sim::closed_loop::{StateSource, StepRecord};
use eemp_sim::walk::WalkSpec;
use eemp_viz::{Recorder as Backend, RerunOptions, RerunTarget};
use std::path::PathBuf;

#[derive(clap::Args, Clone, Debug)]
pub struct RerunArgs {
    /// Record the run for the Rerun viewer: robot, placement ellipses, footholds, forces and
    /// time series (`rerun FILE.rrd` opens it; viewer: pip install rerun-sdk==0.36.3).
    #[arg(long, value_name = "FILE.rrd", conflicts_with_all = ["rerun_connect", "rerun_serve"])]
    pub rerun: Option<PathBuf>,
    /// Stream the recording live to a running viewer: HOST:PORT or rerun+http://HOST:PORT/proxy
    /// (start it with `rerun`; its port is 9876).
    #[arg(long, value_name = "ADDR", conflicts_with = "rerun_serve")]
    pub rerun_connect: Option<String>,
    /// Serve the recording on PORT for a viewer elsewhere (`rerun rerun+http://THIS_HOST:PORT/proxy`);
    /// for a computer without a display. Served while the command runs.
    #[arg(long, value_name = "PORT")]
    pub rerun_serve: Option<u16>,
    /// Recording frames per simulated second, [1, 1000]; touchdowns and pushes are recorded
    /// at the step they happen whatever it is.
    #[arg(long, default_value_t = 100.0)]
    pub rerun_hz: f64,
    /// Record through this Python's rerun-sdk in place of the build's recorder (`eemp bench
    /// viewer` compares them). Not an option: the command line's Python is $EEMP_PYTHON, else
    /// python3.
    #[arg(skip)]
    pub rerun_python: Option<PathBuf>,
}

impl RerunArgs {
    pub fn wanted(&self) -> bool {
        self.rerun.is_some() || self.rerun_connect.is_some() || self.rerun_serve.is_some()
    }

    /// Opens the recorder for a walk of `spec` by `robot` (before the run: a bad path or an
    /// absent viewer is reported now), or a recorder that records nothing without the options.
    pub fn open(
        &self,
        name: &str,
        robot: &eemp_core::robot::RobotConfig,
        spec: &WalkSpec,
    ) -> Result<Recorder, String> {
        if !self.wanted() {
            return Ok(Recorder::none());
        }
        let (robot, scene) = spec.simulated_world(robot);
        self.open_world(World {
            name,
            step_s: robot.simulation.timestep_s,
            robot,
            scene,
            pushes: spec.pushes.clone(),
            estimated: !matches!(spec.state_source, StateSource::GroundTruth),
        })
    }

    /// [`RerunArgs::open`] for any world (a replayed trace).
    pub fn open_world(&self, world: World) -> Result<Recorder, String> {
        let target = match (&self.rerun, &self.rerun_connect, self.rerun_serve) {
            (Some(p), _, _) => RerunTarget::File(p.clone()),
            (_, Some(a), _) => RerunTarget::Connect(a.clone()),
            (_, _, Some(port)) => RerunTarget::Serve(port),
            _ => return Ok(Recorder::none()),
        };
        let describe = match &target {
            RerunTarget::File(p) => format!(
                "recording to {} (open with `rerun {}`)",
                p.display(),
                p.display()
            ),
            RerunTarget::Connect(a) => format!("streaming to the Rerun viewer at {a}"),
            RerunTarget::Serve(port) => {
                format!("serving the recording: rerun rerun+http://THIS_HOST:{port}/proxy")
            }
        };
        let mut options = RerunOptions::new(target);
        options.frame_hz = self.rerun_hz;
        if let Some(py) = &self.rerun_python {
            options.recorder = Backend::Python(py.clone());
        }
        let backend = options.recorder.name();
        let view = eemp_viz::RunView {
            name: world.name.to_string(),
            step_s: world.step_s,
            robot: world.robot,
            scene: world.scene,
            pushes: world.pushes,
            estimated: world.estimated,
        };
        let sink = eemp_viz::RerunSink::open(&options, &view).map_err(|e| e.to_string())?;
        eprintln!("rerun: {describe}, by {backend}");
        Ok(Recorder {
            sink: Some(sink),
            hz: self.rerun_hz,
            backend,
        })
    }
}

/// What a recording draws: the simulated robot and world, and how its steps come.
pub struct World<'a> {
    pub name: &'a str,
    pub robot: eemp_core::robot::RobotConfig,
    pub scene: eemp_sim::mjcf::SceneExtras,
    pub pushes: Vec<eemp_sim::closed_loop::Push>,
    /// The controller saw a state estimate (drawn as a ghost).
    pub estimated: bool,
    /// Time between the steps shown, s.
    pub step_s: f64,
}

/// The run's recorder (or none): an observer on the closed loop.
pub struct Recorder {
    sink: Option<eemp_viz::RerunSink>,
    hz: f64,
    backend: String,
}

impl Recorder {
    fn none() -> Self {
        Recorder {
            sink: None,
            hz: 0.0,
            backend: String::new(),
        }
    }

    pub fn observe(&mut self, record: &StepRecord) {
        if let Some(s) = &mut self.sink {
            s.observe(record);
        }
    }

    /// Writes out what is queued; what the recording holds and lost, for summary.json (None
    /// without a recording). Losses are warned about.
    pub fn finish(self) -> Option<serde_json::Value> {
        if let Some(s) = self.sink {
            let r = s.finish();
            if r.dropped > 0 || r.log_errors > 0 || !r.flushed {
                eprintln!(
                    "warning: the Rerun recording lost {} queued messages and {} log calls{} \
                     (the viewer was slow or went away; the run itself was not slowed)",
                    r.dropped,
                    r.log_errors,
                    if r.flushed {
                        ""
                    } else {
                        ", and was not fully written out in time"
                    }
                );
            }
            return Some(serde_json::json!({
                "rerun_version": eemp_viz::RERUN_VERSION,
                "recorder": self.backend,
                "frame_hz": self.hz,
                "frames": r.frames,
                "touchdowns": r.touchdowns,
                "pushes": r.pushes,
                "dropped": r.dropped,
                "log_errors": r.log_errors,
                "flushed": r.flushed,
            }));
        }
        None
    }
}
