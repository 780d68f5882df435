//! The layout a recording opens with: the 3-D scene beside the time series.

use crate::RunView;
use rerun::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial3DView, Tabs, TimePanel, TimeSeriesView, Vertical,
};
use rerun::RecordingStream;

pub fn default_layout(run: &RunView) -> Blueprint {
    let series = |name: &str, origin: &str| -> ContainerLike {
        TimeSeriesView::new(name).with_origin(origin).into()
    };
    let scene: ContainerLike = Spatial3DView::new(format!("{} — robot and plan", run.name))
        .with_origin("/world")
        .into();
    let plots = Vertical::new([
        series(
            "velocity: commanded vs actual (m/s, rad/s)",
            "/plots/velocity",
        ),
        series(
            "CoT so far (eq. 8, plotted after 0.2 m)",
            "/plots/efficiency/cot",
        ),
        series(
            "manipulability so far (eq. 9)",
            "/plots/efficiency/manipulability",
        ),
        Tabs::new([
            series("joint torques (N·m)", "/plots/torque"),
            series(
                "eq. (5) ellipse value per foot (> 1: outside)",
                "/plots/ellipse",
            ),
            series("touchdown − eq. (6) target (m)", "/plots/touchdown_error_m"),
            series("MPC solve time (ms) and friction μ", "/plots/mpc"),
            series("loaded feet (1 = carrying)", "/plots/contact"),
        ])
        .into(),
    ]);
    Blueprint::new(
        Horizontal::new([scene, plots.with_row_shares([0.3, 0.15, 0.15, 0.4]).into()])
            .with_column_shares([0.6, 0.4]),
    )
    .with_time_panel(TimePanel::new().with_timeline(crate::writer::TIMELINE))
}

/// Static names and colours of the plotted series, so legends read in words and units.
pub fn log_series_styles(
    rec: &RecordingStream,
    estimated: bool,
) -> rerun::RecordingStreamResult<()> {
    let style = |path: &str, name: &str, rgb: [u8; 3]| {
        rec.log_static(
            path,
            &rerun::SeriesLines::new()
                .with_names([name])
                .with_colors([rerun::Color::from_rgb(rgb[0], rgb[1], rgb[2])]),
        )
    };
    let (cmd, act) = ([150, 150, 150], [30, 100, 220]);
    style("plots/velocity/vx/commanded", "vx commanded (m/s)", cmd)?;
    style("plots/velocity/vx/actual", "vx actual (m/s)", act)?;
    style(
        "plots/velocity/vy/commanded",
        "vy commanded (m/s)",
        [190, 160, 120],
    )?;
    style(
        "plots/velocity/vy/actual",
        "vy actual (m/s)",
        [230, 120, 30],
    )?;
    style(
        "plots/velocity/yaw_rate/commanded",
        "yaw rate commanded (rad/s)",
        [160, 190, 160],
    )?;
    style(
        "plots/velocity/yaw_rate/actual",
        "yaw rate actual (rad/s)",
        [40, 160, 60],
    )?;
    if estimated {
        style(
            "plots/velocity/vx/estimated",
            "vx estimated by the filter (m/s)",
            [120, 60, 200],
        )?;
    }
    style(
        "plots/efficiency/cot",
        "CoT so far (eq. 8, −)",
        [200, 40, 40],
    )?;
    style(
        "plots/efficiency/manipulability",
        "manipulability so far (eq. 9)",
        [40, 40, 200],
    )?;
    style(
        "plots/mpc/solve_time_ms",
        "MPC solve time (ms)",
        [100, 100, 100],
    )?;
    style(
        "plots/mpc/friction_mu",
        "MPC friction μ (slip-adapted)",
        [0, 150, 150],
    )?;
    Ok(())
}
