//! A short walk recorded to an .rrd and read back with Rerun's own query engine.

use eemp_core::kinematics::LegKinematics;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::planner::{Gait, PlannerConfig, PlannerParams, VelocityCommand};
use eemp_core::robot::RobotConfig;
use eemp_sim::closed_loop::{Push, StateSource};
use eemp_sim::walk::{run_walk, WalkSpec};
use eemp_viz::{RerunOptions, RerunSink, RerunTarget, RunView};
use nalgebra::Vector3;
use rerun::dataframe::{QueryEngine, QueryExpression};
use rerun::external::arrow::array::{Array, AsArray};
use rerun::external::arrow::datatypes::Float32Type;
use std::path::Path;

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

/// The recording's one data store (the blueprint is another store).
fn engine(path: &Path) -> QueryEngine<rerun::dataframe::StorageEngine> {
    let engines = QueryEngine::from_rrd_filepath(&Default::default(), path).unwrap();
    engines
        .into_iter()
        .find(|(id, _)| id.kind() == rerun::StoreKind::Recording)
        .map(|(_, e)| e)
        .expect("a recording store")
}

/// Rows of `entity` on the simulation timeline, each row's values of the component whose
/// name ends in `component`, flattened to f32.
fn rows(
    engine: &QueryEngine<rerun::dataframe::StorageEngine>,
    entity: &str,
    component: &str,
) -> Vec<Vec<f32>> {
    let query = QueryExpression {
        view_contents: Some([(entity.into(), None)].into_iter().collect()),
        filtered_index: Some("sim_time".into()),
        ..Default::default()
    };
    let mut handle = engine.query(query);
    let column = handle
        .selected_contents()
        .iter()
        .position(|(_, c)| c.display_name().ends_with(component))
        .unwrap_or_else(|| panic!("{entity} has no {component} column"));
    let mut out = Vec::new();
    while let Some(row) = handle.next_row() {
        let cell = &row[column];
        if cell.is_null(0) {
            continue;
        }
        let list = cell.as_list::<i32>().value(0);
        let values = match list.as_fixed_size_list_opt() {
            Some(fixed) => fixed
                .values()
                .as_primitive::<Float32Type>()
                .values()
                .to_vec(),
            None => list.as_primitive::<Float32Type>().values().to_vec(),
        };
        out.push(values);
    }
    out
}

#[test]
fn a_recorded_walk_reads_back_with_its_poses_plan_and_touchdowns() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("walk.rrd");
    let spec = spec(2.0);
    let mut options = RerunOptions::new(RerunTarget::File(path.clone()));
    options.frame_hz = 50.0;
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
    assert!(report.flushed, "{report:?}");
    assert_eq!((report.dropped, report.log_errors), (0, 0), "{report:?}");
    assert_eq!(report.frames, 100, "2 s at 50 Hz");
    assert_eq!(report.pushes, 1);

    let engine = engine(&path);
    let entities: Vec<String> = engine
        .iter_entity_paths_sorted(&rerun::dataframe::EntityPathFilter::all())
        .map(|e| e.to_string())
        .collect();
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
            entities.iter().any(|e| e == expected),
            "{expected} missing from {entities:?}"
        );
    }
    // One trunk pose per frame logged.
    let trunk = rows(&engine, "/world/robot/trunk", "translation");
    assert_eq!(trunk.len(), report.frames);
    // Every touchdown the walk counted, per leg.
    let mut total = 0;
    for leg in Leg::ALL {
        let n = rows(
            &engine,
            &format!("/world/touchdowns/actual/{}", leg.short_name()),
            "positions",
        )
        .len();
        assert_eq!(n, touchdowns[leg], "{leg:?}");
        total += n;
    }
    assert_eq!(total, report.touchdowns);
    assert!(total >= 4, "the walk stepped");
    // Ellipse centres (eq. 5) sit under the hips: the nominal footholds of the true pose.
    let logged = rows(&engine, "/world/plan/ellipse_centres", "positions");
    assert_eq!(logged.len(), centres.len());
    for (row, expected) in logged.iter().zip(&centres) {
        for leg in Leg::ALL {
            let i = leg.index() * 3;
            let e = expected[leg];
            assert!((row[i] as f64 - e.x).abs() < 1e-4 && (row[i + 1] as f64 - e.y).abs() < 1e-4);
        }
    }
}

#[test]
fn a_viewer_that_never_answers_costs_dropped_frames_not_a_hang() {
    // A socket that accepts connections and never speaks gRPC.
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let address = listener.local_addr().unwrap().to_string();
    let spec = spec(2.0);
    let mut options = RerunOptions::new(RerunTarget::Connect(address));
    options.queue_frames = 8;
    let mut sink = RerunSink::open(&options, &view(&spec)).unwrap();
    let run = run_walk(&RobotConfig::a1(), &spec, |r| sink.observe(r)).unwrap();
    assert!(run.metrics.distance_m > 0.2, "{:?}", run.metrics);
    let report = sink.finish();
    // Every frame was queued or counted as dropped; the run never waited for the viewer.
    assert!(report.frames + report.dropped >= 200, "{report:?}");
    drop(listener);
}
