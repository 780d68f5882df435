//! The observer on the closed loop: samples every step into the recorder's queue, never waits.

use crate::frame::{Frame, Message, MpcReading, PushEvent, Touchdown};
use crate::target::RerunOptions;
use crate::writer::{Writer, WriterReport};
use crate::{RunView, VizError};
use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::metrics::MetricsAccumulator;
use eemp_sim::closed_loop::{Push, StepRecord};
use nalgebra::Vector3;
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::time::Duration;

/// The path the trunk has covered before the CoT so far is plotted [m].
pub const MIN_COT_PATH_M: f64 = 0.2;

/// How long [`RerunSink::finish`] waits for the recorder to write out what is queued: longer
/// than a backend's own limit (the Python bridge's 120 s), after which it is stopped.
const FINISH_TIMEOUT: Duration = Duration::from_secs(150);

/// What a recording holds and lost, for the run's summary.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct RerunReport {
    /// Frames queued and logged.
    pub frames: usize,
    pub touchdowns: usize,
    pub pushes: usize,
    /// Messages the loop could not queue (recorder behind or gone).
    pub dropped: usize,
    /// Log calls the recorder could not make (a viewer that went away, a full disk).
    pub log_errors: usize,
    /// Whether everything queued was written out before the time limit.
    pub flushed: bool,
}

/// Records a run to Rerun: hand it every [`StepRecord`] with [`RerunSink::observe`], then
/// call [`RerunSink::finish`].
pub struct RerunSink {
    tx: Option<SyncSender<Message>>,
    done: Receiver<WriterReport>,
    /// Stops a backend that does not finish in time (kills the Python bridge).
    abort: Option<Box<dyn Fn() + Send>>,
    frame_period_s: f64,
    next_frame_s: f64,
    sent: LegMap<usize>,
    frames: usize,
    touchdowns: usize,
    pushes_sent: usize,
    dropped: usize,
    estimated: bool,
    kinematics: LegKinematics,
    metrics: MetricsAccumulator,
    mass_kg: f64,
    dt_s: f64,
    was_loaded: Option<LegMap<bool>>,
    planned_touchdown: LegMap<Option<Vector3<f64>>>,
    pushes: Vec<Push>,
    next_push: usize,
    mpc: Option<MpcReading>,
}

impl RerunSink {
    /// Checks `options` (the file can be written, the viewer listens, …), logs the static
    /// scene and starts the recorder's thread.
    pub fn open(options: &RerunOptions, run: &RunView) -> Result<Self, VizError> {
        options.validate()?;
        if !(run.step_s.is_finite() && run.step_s > 0.0 && run.step_s <= 1.0) {
            return Err(VizError::Option(format!(
                "the time between recorded steps {} s is out of range: allowed (0, 1]",
                run.step_s
            )));
        }
        let layout = crate::layout::default_layout(run);
        let backend = open_backend(
            &options.recorder,
            &crate::backend::Opening {
                target: &options.target,
                recording_name: &run.name,
                layout: &layout,
            },
        )?;
        let abort = backend.abort_handle();
        let writer = Writer::new(backend, run)?;
        let (tx, rx) = mpsc::sync_channel(options.queue_frames);
        let (done_tx, done) = mpsc::channel();
        std::thread::Builder::new()
            .name("eemp-rerun".into())
            .spawn(move || writer.run(rx, done_tx))
            .map_err(|e| VizError::Target(format!("cannot start the recorder thread: {e}")))?;
        let dt_s = run.step_s;
        Ok(RerunSink {
            tx: Some(tx),
            done,
            abort,
            frame_period_s: 1.0 / options.frame_hz,
            next_frame_s: f64::NEG_INFINITY,
            sent: LegMap::splat(0),
            frames: 0,
            touchdowns: 0,
            pushes_sent: 0,
            dropped: 0,
            estimated: run.estimated,
            kinematics: LegKinematics::new(&run.robot),
            metrics: MetricsAccumulator::default(),
            mass_kg: run.robot.total_mass_kg(),
            dt_s,
            was_loaded: None,
            planned_touchdown: LegMap::splat(None),
            pushes: run.pushes.clone(),
            next_push: 0,
            mpc: None,
        })
    }

    fn send(&mut self, message: Message) -> bool {
        let Some(tx) = &self.tx else {
            self.dropped += 1;
            return false;
        };
        match tx.try_send(message) {
            Ok(()) => true,
            Err(TrySendError::Full(_)) => {
                self.dropped += 1;
                false
            }
            Err(TrySendError::Disconnected(_)) => {
                self.dropped += 1;
                self.tx = None;
                false
            }
        }
    }

    /// One control step of the loop.
    pub fn observe(&mut self, record: &StepRecord) {
        let t = record.state.time_s;
        let stance = record.stance();
        eemp_sim::walk::observe_metrics(
            &mut self.metrics,
            &self.kinematics,
            self.dt_s,
            record,
            &stance,
        );
        if let Some(ev) = &record.output.mpc_event {
            self.mpc = Some(MpcReading {
                solve_time_s: ev.solve_time_s,
                friction_coefficient: ev.friction_coefficient,
            });
        }
        let geometry = record.plan.and_then(|p| p.geometry.as_ref());
        if let Some(g) = geometry {
            for leg in Leg::ALL {
                if let Some(s) = g.swings[leg] {
                    self.planned_touchdown[leg] = Some(s.touchdown_world);
                }
            }
        }
        // A touchdown is a foot becoming loaded, as the walk counts them.
        if let Some(prev) = self.was_loaded {
            for leg in Leg::ALL {
                if record.loaded[leg] && !prev[leg] {
                    let td = Touchdown {
                        time_s: t,
                        leg,
                        p_foot_world: record.feet_world[leg],
                        planned_world: self.planned_touchdown[leg].take(),
                    };
                    if self.send(Message::Touchdown(td)) {
                        self.touchdowns += 1;
                        self.sent[leg] += 1;
                    }
                }
            }
        }
        self.was_loaded = Some(record.loaded);
        while self.next_push < self.pushes.len() && self.pushes[self.next_push].at_s <= t {
            let push = &self.pushes[self.next_push];
            let ev = PushEvent {
                time_s: t,
                p_trunk_world: record.state.body.p_world,
                dv_world: push.dv_world,
            };
            self.next_push += 1;
            if self.send(Message::Push(ev)) {
                self.pushes_sent += 1;
            }
        }
        // Half a step of slack: a frame every 1/hz s of simulated time, on the step nearest.
        if t + 0.5 * self.dt_s >= self.next_frame_s {
            self.next_frame_s = if self.next_frame_s.is_finite() {
                self.next_frame_s + self.frame_period_s
            } else {
                t + self.frame_period_s
            };
            let so_far = self.metrics.finish(self.mass_kg);
            let frame = Frame {
                time_s: t,
                truth: *record.state,
                estimate: self.estimated.then_some(*record.estimate),
                command: record.command,
                feet_world: *record.feet_world,
                loaded: record.loaded,
                stance,
                forces_world: record.output.forces_world,
                torques_nm: record.output.torques,
                geometry: geometry.cloned(),
                mpc: self.mpc,
                // Over the first centimetres the CoT is energy over almost no distance: it
                // would set the plot's scale at hundreds and hide the run.
                cot_so_far: so_far
                    .cot
                    .filter(|_| so_far.path_length_m >= MIN_COT_PATH_M),
                manipulability_so_far: so_far.manipulability,
            };
            if self.send(Message::Frame(Box::new(frame))) {
                self.frames += 1;
            }
        }
    }

    /// Touchdowns queued per leg so far.
    pub fn touchdowns_per_leg(&self) -> LegMap<usize> {
        self.sent
    }

    /// Closes the queue and waits (up to a time limit, never forever) for the recorder to
    /// write everything out.
    pub fn finish(mut self) -> RerunReport {
        self.tx = None;
        let (log_errors, flushed) = match self.done.recv_timeout(FINISH_TIMEOUT) {
            Ok(r) => (r.log_errors, r.flushed),
            Err(_) => {
                if let Some(abort) = &self.abort {
                    abort();
                }
                (0, false)
            }
        };
        RerunReport {
            frames: self.frames,
            touchdowns: self.touchdowns,
            pushes: self.pushes_sent,
            dropped: self.dropped,
            log_errors,
            flushed,
        }
    }
}

/// The recorder's backend (the sink picks it, above the backends it can open).
fn open_backend(
    recorder: &crate::backend::Recorder,
    opening: &crate::backend::Opening,
) -> Result<Box<dyn crate::backend::Backend>, VizError> {
    match recorder {
        crate::backend::Recorder::Python(python) => Ok(Box::new(
            crate::python::PythonBackend::open(python, opening)?,
        )),
        #[cfg(feature = "sdk")]
        crate::backend::Recorder::Sdk => Ok(Box::new(crate::sdk::SdkBackend::open(opening)?)),
        #[cfg(not(feature = "sdk"))]
        crate::backend::Recorder::Sdk => Err(VizError::Option(format!(
            "this eemp was built without Rerun's Rust SDK: record through Python (pip install \
             rerun-sdk=={}; ${} picks the Python) or build it with `make viewer`",
            crate::RERUN_VERSION,
            crate::backend::PYTHON_ENV
        ))),
    }
}
