//! A short walk recorded to an .rrd by each recorder this build has, and read back with Rerun's
//! own reader (rerun-sdk's `RrdReader`, tests/read_rrd.py).

use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::{Push, StateSource};
use eemp_sim::walk::{run_walk, WalkSpec};
use eemp_viz::{Recorder, RerunOptions, RerunReport, RerunSink, RerunTarget, RunView};
use nalgebra::Vector3;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

fn spec(duration_s: f64) -> WalkSpec {
    let mut s = WalkSpec::constant(
        PlannerConfig {
            gait: Gait::Free,
            ..Default::default()
        },
        PlannerParams::default(),
        VelocityCommand {
            vx_mps: 0.3,
            ..Default::default()
        },
        duration_s,
    );
    let tables = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../tables");
    s.params_table = Some(
        eemp_core::planner::params_table::ParamsTable::load(&tables.join("a1_free.toml")).unwrap(),
    );
    s.pushes = vec![Push::step(1.0, Vector3::new(0.0, 0.2, 0.0))];
    s.metrics_start_s = 0.0;
    s
}

fn view(spec: &WalkSpec) -> RunView {
    let (robot, scene) = spec.simulated_world(&RobotConfig::a1());
    RunView {
        name: "test walk".into(),
        step_s: robot.simulation.timestep_s,
        robot,
        scene,
        pushes: spec.pushes.clone(),
        estimated: !matches!(spec.state_source, StateSource::GroundTruth),
    }
}

use eemp_viz::testing::python;

/// Everything queued was logged and written out.
fn assert_complete(report: &RerunReport, recorder: &Recorder) {
    assert!(report.flushed, "{recorder:?}: {report:?}");
    assert_eq!(
        (report.dropped, report.log_errors),
        (0, 0),
        "{recorder:?}: {report:?}"
    );
}

/// The recorders this build has: Python's always, the Rust SDK's with the `sdk` feature.
fn recorders(python: &Path) -> Vec<Recorder> {
    let mut r = vec![Recorder::Python(python.to_path_buf())];
    if cfg!(feature = "sdk") {
        r.push(Recorder::Sdk);
    }
    r
}

/// What Rerun's own reader finds in a recording (tests/read_rrd.py).
struct ReadBack {
    entities: Vec<String>,
    rows: HashMap<String, Vec<Vec<f64>>>,
    recording_name: Option<String>,
}

fn read_back(python: &Path, rrd: &Path, wanted: &[String]) -> ReadBack {
    try_read_back(python, rrd, wanted).unwrap_or_else(|e| panic!("{e}"))
}

/// [`read_back`], or why it could not (a file still being written may end mid-chunk).
fn try_read_back(python: &Path, rrd: &Path, wanted: &[String]) -> Result<ReadBack, String> {
    let script = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/read_rrd.py");
    let o = Command::new(python)
        .arg(script)
        .arg(rrd)
        .args(wanted)
        .output()
        .map_err(|e| e.to_string())?;
    if !o.status.success() {
        return Err(String::from_utf8_lossy(&o.stderr).to_string());
    }
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).map_err(|e| e.to_string())?;
    Ok(ReadBack {
        entities: serde_json::from_value(v["entities"].clone()).unwrap(),
        rows: serde_json::from_value(v["rows"].clone()).unwrap(),
        recording_name: v["recording_name"].as_str().map(str::to_string),
    })
}

#[test]
fn a_recorded_walk_reads_back_with_its_poses_plan_and_touchdowns() {
    let Some(python) = python() else { return };
    for recorder in recorders(&python) {
        recorded_walk_reads_back(&python, recorder);
    }
}

fn recorded_walk_reads_back(python: &Path, recorder: Recorder) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("walk.rrd");
    let spec = spec(2.0);
    let mut options = RerunOptions::new(RerunTarget::File(path.clone()));
    options.frame_hz = 50.0;
    options.recorder = recorder.clone();
    let mut sink = RerunSink::open(&options, &view(&spec)).unwrap();
    // What the recording must show, computed beside it from the same steps.
    let kin = LegKinematics::new(&RobotConfig::a1());
    let mut was_loaded: Option<LegMap<bool>> = None;
    let mut touchdowns = LegMap::splat(0usize);
    let mut centres = Vec::new();
    let mut step = 0usize;
    let run = run_walk(&RobotConfig::a1(), &spec, |r| {
        sink.observe(r);
        if let Some(prev) = was_loaded {
            for leg in Leg::ALL {
                touchdowns[leg] += (r.loaded[leg] && !prev[leg]) as usize;
            }
        }
        was_loaded = Some(r.loaded);
        if step.is_multiple_of(20) {
            let b = &r.state.body;
            centres.push(LegMap::from_fn(|leg| {
                b.p_world + b.r_world_body * kin.nominal_foot_body(leg)
            }));
        }
        step += 1;
    })
    .unwrap();
    assert!(
        run.metrics.distance_m > 0.2,
        "the walk walked: {:?}",
        run.metrics
    );
    let report = sink.finish();
    assert_complete(&report, &recorder);
    assert_eq!(report.frames, 100, "2 s at 50 Hz");
    assert_eq!(report.pushes, 1);

    let trunk = "/world/robot/trunk=Transform3D:translation".to_string();
    let centres_key = "/world/plan/ellipse_centres=Points3D:positions".to_string();
    let actual = |leg: Leg| {
        format!(
            "/world/touchdowns/actual/{}=Points3D:positions",
            leg.short_name()
        )
    };
    let rotation = "/world/robot/trunk=Transform3D:quaternion".to_string();
    let colours = "/world/plan/ellipses=LineStrips3D:colors".to_string();
    let mut wanted = vec![
        trunk.clone(),
        centres_key.clone(),
        rotation.clone(),
        colours.clone(),
    ];
    wanted.extend(Leg::ALL.map(actual));
    let back = read_back(python, &path, &wanted);
    assert_eq!(
        back.recording_name.as_deref(),
        Some("test walk"),
        "{recorder:?}"
    );
    for expected in [
        "/world/robot/trunk",
        "/world/robot/trunk/trunk_geom",
        "/world/robot/FR_calf/FR_foot",
        "/world/plan/ellipses",
        "/world/plan/touchdowns",
        "/world/forces",
        "/world/pushes",
        "/plots/velocity/vx/actual",
        "/plots/efficiency/cot",
    ] {
        assert!(
            back.entities.iter().any(|e| e == expected),
            "{recorder:?}: {expected} missing from {:?}",
            back.entities
        );
    }
    // One trunk pose per frame logged.
    assert_eq!(back.rows[&trunk].len(), report.frames, "{recorder:?}");
    // Rerun's quaternions are x, y, z, w: the trunk starts upright and facing +x (w ≈ 1).
    let q0 = &back.rows[&rotation][0];
    assert!(
        q0[3].abs() > 0.99,
        "{recorder:?}: trunk rotation {q0:?} (x, y, z, w)"
    );
    // Each ellipse is green (foot inside) or red (outside), as packed RGBA.
    let packed = |c: [u8; 4]| u32::from_be_bytes(c) as f64;
    for row in &back.rows[&colours] {
        assert_eq!(row.len(), 4, "{recorder:?}: a colour per ellipse");
        for c in row {
            assert!(
                *c == packed([60, 180, 90, 255]) || *c == packed([220, 60, 50, 255]),
                "{recorder:?}: ellipse colour {c:#x}",
                c = *c as u32
            );
        }
    }
    // Every touchdown the walk counted, per leg.
    let mut total = 0;
    for leg in Leg::ALL {
        let n = back.rows[&actual(leg)].len();
        assert_eq!(n, touchdowns[leg], "{recorder:?}: {leg:?}");
        total += n;
    }
    assert_eq!(total, report.touchdowns);
    assert!(total >= 4, "the walk stepped");
    // Ellipse centres (eq. 5) sit under the hips: the nominal footholds of the true pose.
    let logged = &back.rows[&centres_key];
    assert_eq!(logged.len(), centres.len(), "{recorder:?}");
    for (row, expected) in logged.iter().zip(&centres) {
        for leg in Leg::ALL {
            let i = leg.index() * 3;
            let e = expected[leg];
            assert!(
                (row[i] - e.x).abs() < 1e-4 && (row[i + 1] - e.y).abs() < 1e-4,
                "{recorder:?}: {leg:?} centre {row:?} against {e:?}"
            );
        }
    }
}

#[test]
fn a_viewer_that_never_answers_costs_dropped_frames_not_a_hang() {
    let Some(python) = python() else { return };
    for recorder in recorders(&python) {
        viewer_never_answers(recorder);
    }
}

fn viewer_never_answers(recorder: Recorder) {
    let recorder_name = format!("{recorder:?}");
    // A socket that accepts connections and never speaks gRPC.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let spec = spec(2.0);
    let mut options = RerunOptions::new(RerunTarget::Connect(address));
    options.queue_frames = 8;
    options.recorder = recorder;
    let mut sink = RerunSink::open(&options, &view(&spec)).unwrap();
    let run = run_walk(&RobotConfig::a1(), &spec, |r| sink.observe(r)).unwrap();
    assert!(run.metrics.distance_m > 0.2, "{:?}", run.metrics);
    let t0 = Instant::now();
    let report = sink.finish();
    // The recorder gives up on the viewer in its own time (the Python bridge's stream flush
    // 5 s, the SDK's 5 s), well before the sink's last-resort limit.
    assert!(
        t0.elapsed() < Duration::from_secs(30),
        "{recorder_name}: finish took {:?}",
        t0.elapsed()
    );
    // Every frame was queued or counted as dropped; the run never waited for the viewer.
    assert!(report.frames + report.dropped >= 200, "{report:?}");
    drop(listener);
}

#[test]
fn a_live_stream_reaches_a_running_rerun_server() {
    let Some(python) = python() else { return };
    for recorder in recorders(&python) {
        live_stream_reaches_a_server(&python, recorder);
    }
}

/// A child process killed when the test ends, whatever happens in between.
struct KillOnDrop(std::process::Child);

impl Drop for KillOnDrop {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// A real Rerun server (`rerun --port P --save FILE`: the pinned CLI from rerun-sdk, run
/// directly, as a viewer without a window) receives a walk streamed with `--rerun-connect`.
fn live_stream_reaches_a_server(python: &Path, recorder: Recorder) {
    let dir = tempfile::tempdir().unwrap();
    let saved = dir.path().join("received.rrd");
    let cli = Command::new(python)
        .args([
            "-c",
            "import os, rerun_cli; print(os.path.join(os.path.dirname(rerun_cli.__file__), 'rerun'))",
        ])
        .output()
        .unwrap();
    let cli = PathBuf::from(String::from_utf8(cli.stdout).unwrap().trim());
    assert!(cli.exists(), "rerun-sdk's CLI {}", cli.display());
    let port = std::net::TcpListener::bind("127.0.0.1:0")
        .unwrap()
        .local_addr()
        .unwrap()
        .port();
    let server = KillOnDrop(
        Command::new(&cli)
            .args(["--port", &port.to_string(), "--save"])
            .arg(&saved)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    let deadline = Instant::now() + Duration::from_secs(60);
    while std::net::TcpStream::connect(("127.0.0.1", port)).is_err() {
        assert!(
            Instant::now() < deadline,
            "the Rerun server did not listen on {port}"
        );
        std::thread::sleep(Duration::from_millis(100));
    }
    let spec = spec(2.0);
    let mut options = RerunOptions::new(RerunTarget::Connect(format!("127.0.0.1:{port}")));
    options.frame_hz = 50.0;
    options.recorder = recorder.clone();
    let mut sink = RerunSink::open(&options, &view(&spec)).unwrap();
    run_walk(&RobotConfig::a1(), &spec, |r| sink.observe(r)).unwrap();
    let report = sink.finish();
    assert_complete(&report, &recorder);
    // The server writes what it receives as it comes: wait until its file holds every frame
    // sent (a loaded machine may take a while), then stop it.
    let trunk = "/world/robot/trunk=Transform3D:translation".to_string();
    let ellipses = "/world/plan/ellipses=LineStrips3D:strips".to_string();
    let wanted = [trunk.clone(), ellipses.clone()];
    let deadline = Instant::now() + Duration::from_secs(60);
    let received = |b: &ReadBack| {
        b.rows[&trunk].len() == report.frames && b.rows[&ellipses].len() == report.frames
    };
    let back = loop {
        let back = try_read_back(python, &saved, &wanted);
        match back {
            Ok(b) if received(&b) => break b,
            _ if Instant::now() > deadline => panic!(
                "{recorder:?}: the server's file does not hold the {} frames sent: {:?}",
                report.frames,
                back.map(|b| (b.rows[&trunk].len(), b.rows[&ellipses].len()))
            ),
            _ => std::thread::sleep(Duration::from_millis(500)),
        }
    };
    drop(server);
    assert!(
        back.entities.iter().any(|e| e == "/world/forces"),
        "{recorder:?}"
    );
}
