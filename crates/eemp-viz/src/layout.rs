//! The layout a recording opens with (the 3-D scene beside the time series) and the plotted
//! series' names and colours, so that legends read in words and units.

use crate::ops::{rgb, Layout, Op, Ops, Rgba, SeriesView};
use crate::RunView;

pub fn default_layout(run: &RunView) -> Layout {
    let view = |name: &str, origin: &str| SeriesView {
        name: name.into(),
        origin: origin.into(),
    };
    Layout {
        scene_name: format!("{} — robot and plan", run.name),
        scene_origin: "/world".into(),
        rows: vec![
            vec![view(
                "velocity: commanded vs actual (m/s, rad/s)",
                "/plots/velocity",
            )],
            vec![view(
                "CoT so far (eq. 8, plotted after 0.2 m)",
                "/plots/efficiency/cot",
            )],
            vec![view(
                "manipulability so far (eq. 9)",
                "/plots/efficiency/manipulability",
            )],
            vec![
                view("joint torques (N·m)", "/plots/torque"),
                view(
                    "eq. (5) ellipse value per foot (> 1: outside)",
                    "/plots/ellipse",
                ),
                view("touchdown − eq. (6) target (m)", "/plots/touchdown_error_m"),
                view("MPC solve time (ms) and friction μ", "/plots/mpc"),
                view("loaded feet (1 = carrying)", "/plots/contact"),
            ],
        ],
        row_shares: vec![0.3, 0.15, 0.15, 0.4],
        column_shares: [0.6, 0.4],
        timeline: crate::ops::TIMELINE.into(),
    }
}

/// The filter's estimate of vx, plotted only on runs with a state estimate.
pub(crate) const ESTIMATED_VX: &str = "plots/velocity/vx/estimated";

/// The plotted series' legend names (with units) and colours.
const SERIES: [(&str, &str, Rgba); 11] = [
    (
        "plots/velocity/vx/commanded",
        "vx commanded (m/s)",
        rgb(150, 150, 150),
    ),
    (
        "plots/velocity/vx/actual",
        "vx actual (m/s)",
        rgb(30, 100, 220),
    ),
    (
        ESTIMATED_VX,
        "vx estimated by the filter (m/s)",
        rgb(120, 60, 200),
    ),
    (
        "plots/velocity/vy/commanded",
        "vy commanded (m/s)",
        rgb(190, 160, 120),
    ),
    (
        "plots/velocity/vy/actual",
        "vy actual (m/s)",
        rgb(230, 120, 30),
    ),
    (
        "plots/velocity/yaw_rate/commanded",
        "yaw rate commanded (rad/s)",
        rgb(160, 190, 160),
    ),
    (
        "plots/velocity/yaw_rate/actual",
        "yaw rate actual (rad/s)",
        rgb(40, 160, 60),
    ),
    (
        "plots/efficiency/cot",
        "CoT so far (eq. 8, −)",
        rgb(200, 40, 40),
    ),
    (
        "plots/efficiency/manipulability",
        "manipulability so far (eq. 9)",
        rgb(40, 40, 200),
    ),
    (
        "plots/mpc/solve_time_ms",
        "MPC solve time (ms)",
        rgb(100, 100, 100),
    ),
    (
        "plots/mpc/friction_mu",
        "MPC friction μ (slip-adapted)",
        rgb(0, 150, 150),
    ),
];

/// Static names and colours of the plotted series.
pub fn series_styles(ops: &mut Ops, estimated: bool) {
    for (path, name, colour) in SERIES {
        if path == ESTIMATED_VX && !estimated {
            continue;
        }
        ops.push(Op::SeriesStyle {
            path: path.to_string(),
            name: name.to_string(),
            colour,
        });
    }
}
