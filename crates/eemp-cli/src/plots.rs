//! PNG plots: stacked line panels, gait diagrams and heat maps.
//!
//! Text uses DejaVu Sans embedded from the `dejavu` crate and registered with plotters'
//! `ab_glyph` backend on first use, so plots render on machines without any system fonts.

use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use plotters::style::{register_font, FontStyle};
use std::error::Error;
use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Width in pixels of every PNG written here.
pub const WIDTH: u32 = 1200;
const PANEL_H: u32 = 300;
const TITLE_H: u32 = 50;
const LEGEND_W: u32 = 210;
const COLORBAR_W: u32 = 150;
/// Height of the strip under a heat-map grid that explains the grey cells.
const GREY_NOTE_H: u32 = 34;
const FONT: &str = "sans-serif";
const NAN_GREY: RGBColor = RGBColor(176, 176, 176);
const STANCE: RGBColor = RGBColor(31, 119, 180);

/// A plot could not be written; always names the file it was writing.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    #[error("cannot plot {}: the embedded font failed to load", path.display())]
    Font { path: PathBuf },
    #[error("cannot plot {}: {message}", path.display())]
    Draw { path: PathBuf, message: String },
}

/// One line of a panel. Points with a non-finite coordinate are gaps in the line.
#[derive(Debug, Clone, Default)]
pub struct Series {
    pub label: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
}

/// One chart in [`line_panels`]. `markers` are vertical dashed red lines at an x position,
/// named in the legend (repeated labels are listed once).
#[derive(Debug, Clone, Default)]
pub struct Panel {
    pub title: String,
    pub x_label: String,
    pub y_label: String,
    pub series: Vec<Series>,
    pub markers: Vec<(f64, String)>,
    /// Shaded spreads (e.g. min–max over seeds) around series, in their colours.
    pub bands: Vec<Band>,
}

/// A shaded band from `lo` to `hi` at the x values of series `of` of the same panel.
#[derive(Debug, Clone, Default)]
pub struct Band {
    pub of: usize,
    pub lo: Vec<f64>,
    pub hi: Vec<f64>,
}

/// One small map in [`heatmap_grid`]; `z[iy][ix]` as for [`heatmap`].
#[derive(Debug, Clone, Default)]
pub struct HeatmapCell {
    pub title: String,
    pub x: Vec<f64>,
    pub y: Vec<f64>,
    pub z: Vec<Vec<f64>>,
}

type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;
type DrawResult<T = ()> = Result<T, Box<dyn Error>>;

/// Panels stacked vertically in one PNG (1200 px wide, 300 px per panel) under `title`.
pub fn line_panels(path: &Path, title: &str, panels: &[Panel]) -> Result<(), PlotError> {
    let height = TITLE_H + PANEL_H * panels.len().max(1) as u32;
    render(path, (WIDTH, height), |root| {
        let body = root.titled(title, title_style())?;
        if panels.is_empty() {
            return no_data(&body);
        }
        for (panel, area) in panels.iter().zip(body.split_evenly((panels.len(), 1))) {
            draw_panel(&area, panel)?;
        }
        Ok(())
    })
}

/// Gait diagram: one lane per leg (top to bottom in `leg_names` order), filled where the
/// leg is in stance. Sample `i` covers `time[i]..time[i + 1]`.
pub fn gait_diagram(
    path: &Path,
    title: &str,
    time: &[f64],
    stance: &[[bool; 4]],
    leg_names: [&str; 4],
) -> Result<(), PlotError> {
    render(path, (WIDTH, 360), |root| {
        let body = root.titled(title, title_style())?;
        let (chart_area, legend) = body.split_horizontally(WIDTH - LEGEND_W);
        let (t0, t1) = axis_range(time.iter().copied());
        let mut chart = ChartBuilder::on(&chart_area)
            .margin(10)
            .x_label_area_size(45)
            .y_label_area_size(90)
            .build_cartesian_2d(t0..t1, -0.5f64..3.5f64)?;
        chart
            .configure_mesh()
            .disable_y_mesh()
            .y_labels(8)
            .y_label_formatter(&|v| lane_name(*v, &leg_names))
            .x_desc("time [s]")
            .x_label_formatter(&tick_format((t0, t1)))
            .label_style((FONT, 14))
            .axis_desc_style((FONT, 16))
            .draw()?;
        for leg in 0..4 {
            let lane = 3.0 - leg as f64;
            let (lo, hi) = (lane - 0.35, lane + 0.35);
            let outline = Rectangle::new([(t0, lo), (t1, hi)], BLACK.mix(0.3));
            chart.draw_series([outline])?;
            let bars = stance_runs(time, stance, leg)
                .into_iter()
                .map(|(a, b)| Rectangle::new([(a, lo), (b, hi)], STANCE.filled()));
            chart.draw_series(bars)?;
        }
        draw_legend(&legend, &[("stance".into(), Swatch::Bar(STANCE))], 45)
    })
}

/// Heat map of `z[iy][ix]` over cell centres `x`, `y`, with a colour bar labelled `z_label`.
/// Non-finite cells are grey and listed as "fell / no data" under the colour bar.
#[allow(clippy::too_many_arguments)]
pub fn heatmap(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    z_label: &str,
    x: &[f64],
    y: &[f64],
    z: &[Vec<f64>],
) -> Result<(), PlotError> {
    let zr = padded_range(z.iter().flatten().copied(), 0.0);
    render(path, (WIDTH, 800), |root| {
        let body = root.titled(title, title_style())?;
        let (map, side) = body.split_horizontally(WIDTH - COLORBAR_W);
        let (bar, note) = side.split_vertically(side.dim_in_pixel().1 - 70);
        let labels = (x_label, y_label, 16);
        let grey = draw_map(&map, "", labels, x, y, z, zr)?;
        draw_colorbar(&bar, z_label, zr, 15)?;
        if grey {
            draw_legend(&note, &[grey_entry()], 10)?;
        }
        Ok(())
    })
}

/// Small heat maps in a grid `cols` wide, filled row by row. Each row of the grid has its own
/// colour scale, shown by its own colour bar on the right (for one speed per row, the panels
/// of that speed are comparable with each other, and a row of low values is not flattened by
/// the high values of another).
pub fn heatmap_grid(
    path: &Path,
    title: &str,
    x_label: &str,
    y_label: &str,
    z_label: &str,
    cells: &[HeatmapCell],
    cols: usize,
) -> Result<(), PlotError> {
    let cols = cols.clamp(1, cells.len().max(1));
    let rows = cells.len().div_ceil(cols).max(1);
    let cell_h = ((WIDTH - COLORBAR_W) / cols as u32 * 4 / 5).clamp(260, 500);
    let height = TITLE_H + cell_h * rows as u32 + GREY_NOTE_H;
    render(path, (WIDTH, height), |root| {
        let body = root.titled(title, title_style())?;
        let (main, note) = body.split_vertically(cell_h * rows as u32);
        let (grid, bars) = main.split_horizontally(WIDTH - COLORBAR_W);
        if cells.is_empty() {
            return no_data(&grid);
        }
        let areas = grid.split_evenly((rows, cols));
        let mut grey = false;
        for ((row, row_areas), bar) in cells
            .chunks(cols)
            .zip(areas.chunks(cols))
            .zip(bars.split_evenly((rows, 1)))
        {
            let zr = padded_range(row.iter().flat_map(|c| c.z.iter().flatten().copied()), 0.0);
            for (cell, area) in row.iter().zip(row_areas) {
                let (x, y, z) = (&cell.x, &cell.y, &cell.z);
                grey |= draw_map(area, &cell.title, (x_label, y_label, 13), x, y, z, zr)?;
            }
            // The bar spans the maps' plotting height: below the captions, above the x axes.
            let (_, bar) = bar.split_vertically(13 + 2 + 8 + 10);
            let (bar, _) = bar.split_vertically(bar.dim_in_pixel().1.saturating_sub(13 * 3));
            draw_colorbar(&bar, z_label, zr, 13)?;
        }
        if grey {
            let (_, right) = note.split_horizontally(WIDTH - COLORBAR_W - 60);
            draw_legend(&right, &[grey_entry()], 4)?;
        }
        Ok(())
    })
}

fn grey_entry() -> (String, Swatch) {
    ("fell / no data".into(), Swatch::Bar(NAN_GREY))
}

/// Registers the embedded font once (plots and video overlays draw text with it).
pub fn ensure_font() -> Result<(), String> {
    static FONT_OK: OnceLock<bool> = OnceLock::new();
    let ok = *FONT_OK.get_or_init(|| {
        register_font(FONT, FontStyle::Normal, dejavu::sans::regular()).is_ok()
            && register_font(FONT, FontStyle::Bold, dejavu::sans::bold()).is_ok()
    });
    if ok {
        Ok(())
    } else {
        Err("cannot register the embedded font".into())
    }
}

fn render(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&Area) -> DrawResult,
) -> Result<(), PlotError> {
    if ensure_font().is_err() {
        return Err(PlotError::Font { path: path.into() });
    }
    let draw_err = |e: Box<dyn Error>| PlotError::Draw {
        path: path.into(),
        message: e.to_string(),
    };
    // plotters only reports a bad path when it saves, after all the drawing; fail early.
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| draw_err(e.into()))?;
    }
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE).map_err(|e| draw_err(e.into()))?;
    draw(&root).map_err(draw_err)?;
    root.present().map_err(|e| draw_err(e.into()))
}

fn title_style() -> TextStyle<'static> {
    // `FontDesc::style` keeps the old glyph data, so ask for the bold face directly.
    FontDesc::new(FontFamily::Name(FONT), 26.0, FontStyle::Bold).into()
}

fn no_data(area: &Area) -> DrawResult {
    let (w, h) = area.dim_in_pixel();
    let style = TextStyle::from((FONT, 20)).pos(Pos::new(HPos::Center, VPos::Center));
    area.draw_text("no data", &style, (w as i32 / 2, h as i32 / 2))?;
    Ok(())
}

fn draw_panel(area: &Area, panel: &Panel) -> DrawResult {
    let (chart_area, legend) = area.split_horizontally(WIDTH - LEGEND_W);
    let points = || panel.series.iter().flat_map(finite_points);
    let xr = axis_range(
        points()
            .map(|p| p.0)
            .chain(panel.markers.iter().map(|m| m.0)),
    );
    let yr = axis_range(points().map(|p| p.1));
    let mut chart = ChartBuilder::on(&chart_area)
        .caption(&panel.title, (FONT, 18))
        .margin(8)
        .x_label_area_size(42)
        .y_label_area_size(80)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
    chart
        .configure_mesh()
        .x_desc(panel.x_label.as_str())
        .y_desc(panel.y_label.as_str())
        .x_label_formatter(&tick_format(xr))
        .y_label_formatter(&tick_format(yr))
        .label_style((FONT, 13))
        .axis_desc_style((FONT, 15))
        .light_line_style(BLACK.mix(0.05))
        .draw()?;
    for band in &panel.bands {
        let Some(series) = panel.series.get(band.of) else {
            continue;
        };
        let pts: Vec<(f64, f64, f64)> = series
            .x
            .iter()
            .zip(band.lo.iter().zip(&band.hi))
            .filter(|(x, (l, h))| x.is_finite() && l.is_finite() && h.is_finite())
            .map(|(x, (l, h))| (*x, *l, *h))
            .collect();
        if pts.len() >= 2 {
            let poly: Vec<(f64, f64)> = pts
                .iter()
                .map(|p| (p.0, p.2))
                .chain(pts.iter().rev().map(|p| (p.0, p.1)))
                .collect();
            chart.draw_series([Polygon::new(poly, palette(band.of).mix(0.18).filled())])?;
        }
    }
    let mut entries = Vec::new();
    let has_data = |s: &&Series| finite_points(s).next().is_some();
    for (i, series) in panel.series.iter().filter(has_data).enumerate() {
        let color = palette(i);
        for seg in segments(series) {
            if let [p] = seg[..] {
                chart.draw_series([Circle::new(p, 2, color.filled())])?;
            } else {
                chart.draw_series(LineSeries::new(seg, color.stroke_width(2)))?;
            }
        }
        entries.push((series.label.clone(), Swatch::Line(color)));
    }
    for (x, label) in panel.markers.iter().filter(|m| m.0.is_finite()) {
        let line = [(*x, yr.0), (*x, yr.1)];
        chart.draw_series(DashedLineSeries::new(line, 8, 6, RED.stroke_width(2)))?;
        let entry = (label.clone(), Swatch::Dashed(RED));
        if !entries.contains(&entry) {
            entries.push(entry);
        }
    }
    draw_legend(&legend, &entries, 36)
}

/// Draws the heat map into `area`; returns whether any cell was grey (no data).
fn draw_map(
    area: &Area,
    title: &str,
    (x_label, y_label, text): (&str, &str, u32),
    x: &[f64],
    y: &[f64],
    z: &[Vec<f64>],
    zr: (f64, f64),
) -> DrawResult<bool> {
    let (ex, ey) = (cell_edges(x), cell_edges(y));
    let span = |e: &[(usize, f64, f64)]| match (e.first(), e.last()) {
        (Some(a), Some(b)) => (a.1.min(b.2), a.1.max(b.2)),
        _ => (0.0, 1.0),
    };
    let (xr, yr) = (span(&ex), span(&ey));
    let mut builder = ChartBuilder::on(area);
    if !title.is_empty() {
        builder.caption(title, (FONT, text + 2));
    }
    let mut chart = builder
        .margin(8)
        .x_label_area_size(text * 3)
        .y_label_area_size(text * 5)
        .build_cartesian_2d(xr.0..xr.1, yr.0..yr.1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc(x_label)
        .y_desc(y_label)
        .x_label_formatter(&tick_format(xr))
        .y_label_formatter(&tick_format(yr))
        .label_style((FONT, text - 2))
        .axis_desc_style((FONT, text))
        .draw()?;
    let mut grey = ex.is_empty() || ey.is_empty();
    let mut rects = Vec::with_capacity(ex.len() * ey.len());
    for &(iy, y0, y1) in &ey {
        for &(ix, x0, x1) in &ex {
            let v = z.get(iy).and_then(|row| row.get(ix)).copied();
            let color = match v.filter(|v| v.is_finite()) {
                Some(v) => colormap((v - zr.0) / (zr.1 - zr.0)),
                None => {
                    grey = true;
                    NAN_GREY
                }
            };
            rects.push(Rectangle::new([(x0, y0), (x1, y1)], color.filled()));
        }
    }
    chart.draw_series(rects)?;
    Ok(grey)
}

/// A vertical colour bar filling `area`, its label written horizontally above it (a rotated
/// label beside the ticks does not fit a narrow bar and was clipped at the image edge).
fn draw_colorbar(area: &Area, z_label: &str, zr: (f64, f64), text: u32) -> DrawResult {
    let label_h = text as i32 + 10;
    let (w, _) = area.dim_in_pixel();
    let style = TextStyle::from((FONT, text)).pos(Pos::new(HPos::Center, VPos::Top));
    let bar_w = 26;
    let left = 12;
    // Centred over the bar and its ticks, kept inside the area.
    let label_w = area.estimate_text_size(z_label, &style)?.0 as i32;
    let cx = (left + bar_w / 2 + 10)
        .max(label_w / 2 + 2)
        .min(w as i32 - label_w / 2 - 2);
    area.draw_text(z_label, &style, (cx, 0))?;
    let tick_w = w.saturating_sub((left + bar_w) as u32 + 4).max(10);
    let mut chart = ChartBuilder::on(area)
        .margin_top(label_h)
        .margin_bottom(text / 2 + 2)
        .margin_left(left)
        .right_y_label_area_size(tick_w)
        .build_cartesian_2d(0.0f64..1.0f64, zr.0..zr.1)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .disable_x_axis()
        .y_labels(((area.dim_in_pixel().1 / 40) as usize).clamp(3, 10))
        .y_label_formatter(&tick_format(zr))
        .label_style((FONT, text - 1))
        .draw()?;
    let steps = 200;
    let dz = (zr.1 - zr.0) / steps as f64;
    chart.draw_series((0..steps).map(|i| {
        let z0 = zr.0 + dz * i as f64;
        let color = colormap((i as f64 + 0.5) / steps as f64);
        Rectangle::new([(0.0, z0), (1.0, z0 + dz)], color.filled())
    }))?;
    Ok(())
}

#[derive(PartialEq)]
enum Swatch {
    Line(RGBColor),
    Dashed(RGBColor),
    Bar(RGBColor),
}

/// Legends live beside the chart so they never hide data. A label too wide for the area is
/// wrapped at spaces onto further lines (at most [`LEGEND_LINES`]; only then is it cut).
fn draw_legend(area: &Area, entries: &[(String, Swatch)], top: i32) -> DrawResult {
    let (w, h) = area.dim_in_pixel();
    let row = ((h as i32 - top - 10) / entries.len().max(1) as i32).clamp(8, 22);
    let size = (row - 6).clamp(9, 14);
    let style = TextStyle::from((FONT, size)).pos(Pos::new(HPos::Left, VPos::Center));
    let max_w = w.saturating_sub(56);
    let line_h = size + 3;
    let mut y = top + row / 2;
    for (label, swatch) in entries {
        let (a, b) = ((8, y), (38, y));
        match swatch {
            Swatch::Line(c) => area.draw(&PathElement::new([a, b], c.stroke_width(3)))?,
            Swatch::Dashed(c) => {
                for x in [8, 20, 32] {
                    area.draw(&PathElement::new([(x, y), (x + 7, y)], c.stroke_width(2)))?;
                }
            }
            Swatch::Bar(c) => {
                let half = (row / 3).max(3);
                let corners = [(8, y - half), (38, y + half)];
                area.draw(&Rectangle::new(corners, c.filled()))?;
            }
        }
        let fits = |t: &str| -> Result<bool, Box<dyn Error>> {
            Ok(area.estimate_text_size(t, &style)?.0 <= max_w)
        };
        let lines = wrap_text(label, LEGEND_LINES, fits)?;
        for (k, line) in lines.iter().enumerate() {
            area.draw_text(line, &style, (46, y + k as i32 * line_h))?;
        }
        y += row + (lines.len() as i32 - 1) * line_h;
    }
    Ok(())
}

/// Most lines one legend label may take.
const LEGEND_LINES: usize = 3;

/// `text` in at most `max_lines` lines that each satisfy `fits`, broken at spaces; a word too
/// long for a line, or text beyond the last line, is cut with "…".
fn wrap_text(
    text: &str,
    max_lines: usize,
    fits: impl Fn(&str) -> Result<bool, Box<dyn Error>>,
) -> Result<Vec<String>, Box<dyn Error>> {
    let cut = |t: &str| -> Result<String, Box<dyn Error>> {
        let mut t = t.to_string();
        while t.chars().count() > 1 && !fits(&t)? {
            t.pop();
            t.pop();
            t.push('…');
        }
        Ok(t)
    };
    let mut lines: Vec<String> = Vec::new();
    let mut words = text.split(' ').peekable();
    while let Some(word) = words.next() {
        let mut line = word.to_string();
        while let Some(next) = words.peek() {
            let longer = format!("{line} {next}");
            if !fits(&longer)? {
                break;
            }
            line = longer;
            words.next();
        }
        if lines.len() + 1 == max_lines && words.peek().is_some() {
            let rest: Vec<&str> = words.collect();
            line = format!("{line} {}", rest.join(" "));
            lines.push(cut(&line)?);
            return Ok(lines);
        }
        lines.push(cut(&line)?);
    }
    if lines.is_empty() {
        lines.push(String::new());
    }
    Ok(lines)
}

/// Tick labels with the decimals the tick spacing needs; plotters' own shows "-0.0".
fn tick_format(range: (f64, f64)) -> impl Fn(&f64) -> String {
    let step = (range.1 - range.0) / 10.0;
    let decimals = (-step.log10().floor()).clamp(0.0, 12.0) as usize;
    move |v| {
        let text = if v.abs() >= 1e6 || decimals > 5 {
            format!("{v:.2e}")
        } else {
            format!("{v:.decimals$}")
        };
        match text.strip_prefix('-') {
            Some(rest) if text.parse::<f64>() == Ok(0.0) => rest.to_string(),
            _ => text,
        }
    }
}

fn lane_name(v: f64, names: &[&str; 4]) -> String {
    let lane = v.round();
    if (v - lane).abs() > 1e-6 || !(0.0..=3.0).contains(&lane) {
        return String::new();
    }
    names[3 - lane as usize].to_string()
}

/// Stance intervals of one leg; a non-finite time ends the current interval.
fn stance_runs(time: &[f64], stance: &[[bool; 4]], leg: usize) -> Vec<(f64, f64)> {
    let n = time.len().min(stance.len());
    let mut runs = Vec::new();
    let mut start: Option<f64> = None;
    for i in 0..n {
        let t = time[i];
        let on = t.is_finite() && stance[i][leg];
        match (start, on) {
            (None, true) => start = Some(t),
            (Some(s), false) => {
                runs.push((s, if t.is_finite() { t } else { time[i - 1] }));
                start = None;
            }
            _ => {}
        }
    }
    if let Some(s) = start {
        runs.push((s, time[n - 1]));
    }
    runs
}

fn finite_points(s: &Series) -> impl Iterator<Item = (f64, f64)> + '_ {
    let pts = s.x.iter().zip(&s.y).map(|(&x, &y)| (x, y));
    pts.filter(|(x, y)| x.is_finite() && y.is_finite())
}

/// Runs of consecutive finite points, so gaps in the data stay gaps in the line.
fn segments(s: &Series) -> Vec<Vec<(f64, f64)>> {
    let mut out = vec![Vec::new()];
    for (&x, &y) in s.x.iter().zip(&s.y) {
        if x.is_finite() && y.is_finite() {
            if let Some(seg) = out.last_mut() {
                seg.push((x, y));
            }
        } else if out.last().is_some_and(|seg| !seg.is_empty()) {
            out.push(Vec::new());
        }
    }
    out.retain(|seg| !seg.is_empty());
    out
}

fn axis_range(values: impl Iterator<Item = f64>) -> (f64, f64) {
    padded_range(values, 0.05)
}

/// Finite min..max widened by `margin` of the span; never empty, so plotters always gets
/// a usable range even for constant or missing data.
fn padded_range(values: impl Iterator<Item = f64>, margin: f64) -> (f64, f64) {
    let (lo, hi) = values
        .filter(|v| v.is_finite())
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), v| {
            (lo.min(v), hi.max(v))
        });
    if lo > hi {
        return (0.0, 1.0);
    }
    let span = hi - lo;
    let flat_pad = (0.1 * lo.abs()).max(0.5);
    let pad = if span > 0.0 { margin * span } else { flat_pad };
    if !span.is_finite() || !(lo - pad).is_finite() || !(hi + pad).is_finite() {
        return (-f64::MAX / 4.0, f64::MAX / 4.0);
    }
    (lo - pad, hi + pad)
}

/// (index, lower edge, upper edge) of each finite grid value: edges half-way to the neighbours.
fn cell_edges(v: &[f64]) -> Vec<(usize, f64, f64)> {
    let finite = v.iter().copied().enumerate().filter(|p| p.1.is_finite());
    let pts: Vec<(usize, f64)> = finite.collect();
    (0..pts.len())
        .map(|k| {
            let c = pts[k].1;
            let half = |o: Option<&(usize, f64)>| o.map(|p| (p.1 - c) / 2.0);
            let up = half(pts.get(k + 1));
            let down = half(k.checked_sub(1).and_then(|j| pts.get(j)));
            // A lone value: a band ±10 % of it wide (±0.5 around 0).
            let lone = if c != 0.0 { 0.1 * c.abs() } else { 0.5 };
            let up = up.or(down.map(|d| -d)).unwrap_or(lone);
            let down = down.unwrap_or(-up);
            (pts[k].0, c + down, c + up)
        })
        .collect()
}

fn palette(i: usize) -> RGBColor {
    // Tableau colours without red, which is reserved for the marker lines.
    const P: [u32; 9] = [
        0x1f77b4, 0xff7f0e, 0x2ca02c, 0x9467bd, 0x8c564b, 0xe377c2, 0x7f7f7f, 0xbcbd22, 0x17becf,
    ];
    match P.get(i) {
        Some(&c) => hex(c),
        None => {
            let (r, g, b) = HSLColor((i as f64 * 0.618_034).fract(), 0.7, 0.4).rgb();
            RGBColor(r, g, b)
        }
    }
}

fn hex(c: u32) -> RGBColor {
    RGBColor((c >> 16) as u8, (c >> 8) as u8, c as u8)
}

/// Viridis, sampled at five stops and interpolated linearly.
fn colormap(t: f64) -> RGBColor {
    const STOPS: [u32; 5] = [0x440154, 0x3b528b, 0x21918c, 0x5ec962, 0xfde725];
    // Callers grey out NaN first; were one to slip through, the `as` casts saturate.
    let s = t.clamp(0.0, 1.0) * 4.0;
    let i = (s.floor() as usize).min(3);
    let (a, b, f) = (hex(STOPS[i]), hex(STOPS[i + 1]), s - i as f64);
    let mix = |p: u8, q: u8| (p as f64 + (q as f64 - p as f64) * f).round() as u8;
    RGBColor(mix(a.0, b.0), mix(a.1, b.1), mix(a.2, b.2))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A fresh folder per test and process; kept afterwards only if EEMP_KEEP_PLOTS is set,
    /// so the pictures can be looked at.
    struct Out(PathBuf);
    impl Out {
        fn new(test: &str) -> Self {
            let dir =
                std::env::temp_dir().join(format!("eemp-plots-{}-{test}", std::process::id()));
            std::fs::create_dir_all(&dir).unwrap();
            Out(dir)
        }
        /// Draws into `name` and checks the PNG signature and the IHDR width.
        fn check(&self, name: &str, draw: impl FnOnce(&Path) -> Result<(), PlotError>) {
            let path = self.0.join(name);
            draw(&path).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{name}");
            assert_eq!(&bytes[12..16], b"IHDR");
            assert_eq!(u32::from_be_bytes(bytes[16..20].try_into().unwrap()), WIDTH);
        }
    }
    impl Drop for Out {
        fn drop(&mut self) {
            if std::env::var_os("EEMP_KEEP_PLOTS").is_none() {
                let _ = std::fs::remove_dir_all(&self.0);
            }
        }
    }

    fn series(label: &str, f: impl Fn(f64) -> f64) -> Series {
        let x: Vec<f64> = (0..500).map(|i| i as f64 * 0.01).collect();
        let y = x.iter().map(|&t| f(t)).collect();
        Series {
            label: label.into(),
            x,
            y,
        }
    }

    fn panel(title: &str, series: Vec<Series>) -> Panel {
        let (x_label, y_label) = ("time [s]".into(), "value [m]".into());
        Panel {
            title: title.into(),
            x_label,
            y_label,
            series,
            markers: vec![],
            bands: vec![],
        }
    }

    fn grid(nx: usize, ny: usize, f: impl Fn(f64, f64) -> f64) -> HeatmapCell {
        let x: Vec<f64> = (0..nx).map(|i| i as f64 * 0.1).collect();
        let y: Vec<f64> = (0..ny).map(|i| -0.7 + i as f64 * 0.1).collect();
        let z = y
            .iter()
            .map(|&b| x.iter().map(|&a| f(a, b)).collect())
            .collect();
        HeatmapCell {
            title: String::new(),
            x,
            y,
            z,
        }
    }

    #[test]
    fn line_panels_draw_markers_gaps_constants_and_empty_series() {
        let out = Out::new("line_panels");
        let mut gappy = series("with NaN gap", |t| (3.0 * t).sin());
        gappy.y[100..150].fill(f64::NAN);
        gappy.x[300] = f64::INFINITY;
        let mut first = panel("base height", vec![series("z", |t| 0.3 + 0.01 * t), gappy]);
        first.markers = [(1.0, "push"), (3.0, "push"), (4.0, "land"), (f64::NAN, "x")]
            .map(|(x, l)| (x, l.to_string()))
            .to_vec();
        let many = (0..12).map(|k| series(&format!("joint {k}"), move |t| t * k as f64));
        let panels = [
            first,
            panel("constant", vec![series("zero torque", |_| 0.0)]),
            panel("twelve joints", many.collect()),
            panel(
                "empty",
                vec![series("nothing", |_| f64::NAN), Series::default()],
            ),
        ];
        out.check("panels.png", |p| line_panels(p, "Walk 0.5 m/s", &panels));
        out.check("none.png", |p| line_panels(p, "no panels", &[]));
    }

    #[test]
    fn gait_diagram_draws_stance_bars_and_survives_bad_input() {
        let out = Out::new("gait");
        let time: Vec<f64> = (0..400).map(|i| i as f64 * 0.005).collect();
        let phase = |t: f64| (t / 0.5).fract();
        let stance: Vec<[bool; 4]> = time
            .iter()
            .map(|&t| (phase(t) < 0.6, !(0.5..0.9).contains(&phase(t))))
            .map(|(a, b)| [a, b, b, a])
            .collect();
        let legs = ["FL", "FR", "RL", "RR"];
        out.check("gait.png", |p| {
            gait_diagram(p, "Trot gait", &time, &stance, legs)
        });
        let mut bad_time = time.clone();
        bad_time[2] = f64::NAN;
        out.check("odd.png", |p| {
            gait_diagram(p, "odd", &bad_time, &stance[..5], legs)
        });
        out.check("empty.png", |p| gait_diagram(p, "empty", &[], &[], legs));
    }

    #[test]
    fn heatmap_greys_nan_and_missing_cells() {
        let out = Out::new("heatmap");
        let mut g = grid(20, 15, |a, b| a * a - b);
        g.z[3][4] = f64::NAN;
        g.z[14].truncate(10);
        let map = |name: &str, x: &[f64], y: &[f64], z: &[Vec<f64>]| {
            out.check(name, |p| {
                heatmap(p, name, "kp [-]", "kd [-]", "speed [m/s]", x, y, z)
            });
        };
        map("heatmap.png", &g.x, &g.y, &g.z);
        map(
            "nan.png",
            &[0.0, 1.0],
            &[1.0, 2.0],
            &vec![vec![f64::NAN; 2]; 2],
        );
        map("empty.png", &[], &[], &[]);
    }

    #[test]
    fn heatmap_grid_has_a_colour_scale_per_row() {
        let out = Out::new("heatmap_grid");
        let cells: Vec<HeatmapCell> = (0..5)
            .map(|k| {
                let mut cell = grid(10, 8, |a, b| a + b * k as f64);
                cell.z[0][0] = f64::NAN;
                HeatmapCell {
                    title: format!("payload {k} kg"),
                    ..cell
                }
            })
            .collect();
        let (x, y, z) = ("kp [-]", "kd [-]", "speed [m/s]");
        out.check("grid.png", |p| {
            heatmap_grid(p, "Speed sweep", x, y, z, &cells, 3)
        });
        out.check("empty.png", |p| heatmap_grid(p, "none", x, y, z, &[], 0));
        let odd = [HeatmapCell {
            title: "empty cell".into(),
            ..Default::default()
        }];
        out.check("odd.png", |p| heatmap_grid(p, "odd", x, y, z, &odd, 5));
    }

    #[test]
    fn unwritable_path_error_names_the_path() {
        let out = Out::new("unwritable");
        let file = out.0.join("a-file");
        std::fs::write(&file, b"x").unwrap();
        let path = file.join("plot.png");
        let one = [vec![1.0]];
        let errors = [
            line_panels(&path, "t", &[panel("p", vec![series("s", |t| t)])]),
            gait_diagram(
                &path,
                "t",
                &[0.0, 1.0],
                &[[true; 4]; 2],
                ["a", "b", "c", "d"],
            ),
            heatmap(&path, "t", "x", "y", "z", &[0.0], &[0.0], &one),
            heatmap_grid(&path, "t", "x", "y", "z", &[], 2),
        ];
        for result in errors {
            let message = result.unwrap_err().to_string();
            assert!(message.contains(&path.display().to_string()), "{message}");
        }
    }

    #[test]
    fn ranges_ticks_and_segments() {
        assert_eq!(axis_range([f64::NAN].into_iter()), (0.0, 1.0));
        let (lo, hi) = axis_range([2.0, 2.0].into_iter());
        assert!(lo < 2.0 && hi > 2.0);
        let (lo, hi) = axis_range([0.0, 10.0, f64::INFINITY].into_iter());
        assert!((lo + 0.5).abs() < 1e-12 && (hi - 10.5).abs() < 1e-12);
        let edges = vec![(0, -0.5, 0.5), (1, 0.5, 2.0), (2, 2.0, 4.0)];
        assert_eq!(cell_edges(&[0.0, 1.0, 3.0]), edges);
        let f = tick_format((-1.1, 1.1));
        assert_eq!([f(&-0.0001), f(&0.4), f(&-1.0)], ["0.0", "0.4", "-1.0"]);
        assert_eq!(tick_format((0.0, 60.0))(&50.0), "50");
        let gap = series("s", |t| if (1.0..2.0).contains(&t) { f64::NAN } else { t });
        assert_eq!(segments(&gap).len(), 2);
        let lone = cell_edges(&[0.07]);
        assert!((lone[0].1 - 0.063).abs() < 1e-12 && (lone[0].2 - 0.077).abs() < 1e-12);
    }

    #[test]
    fn legend_labels_wrap_at_spaces_and_are_cut_only_beyond_the_last_line() {
        let fits = |t: &str| Ok::<bool, Box<dyn Error>>(t.chars().count() <= 10);
        let wrap = |t: &str, n: usize| wrap_text(t, n, fits).unwrap();
        assert_eq!(wrap("short", 3), ["short"]);
        assert_eq!(
            wrap("walk unstable from 0.5 m/s", 3),
            ["walk", "unstable", "from 0.5 …"]
        );
        assert_eq!(
            wrap("walk unstable from 0.5 m/s", 4),
            ["walk", "unstable", "from 0.5", "m/s"]
        );
        assert_eq!(wrap("abcdefghijklmno", 2), ["abcdefghi…"]);
        assert_eq!(wrap("", 2), [""]);
    }
}

/// One frame of [`stick_figures`]: polylines of two figures in a side view.
#[derive(Debug, Clone, Default)]
pub struct StickFrame {
    pub title: String,
    pub a: Vec<Vec<(f64, f64)>>,
    pub b: Vec<Vec<(f64, f64)>>,
}

/// Stick figures of two bodies (e.g. the dog's markers and the robot's links) frame by frame,
/// side by side, with equal axis scales in every frame.
pub fn stick_figures(
    path: &Path,
    title: &str,
    (x_label, y_label): (&str, &str),
    (label_a, label_b): (&str, &str),
    frames: &[StickFrame],
) -> Result<(), PlotError> {
    let cols = frames.len().clamp(1, 4);
    let rows = frames.len().div_ceil(cols).max(1);
    let cell = 300u32;
    let width = cell * cols as u32 + LEGEND_W;
    render(path, (width, TITLE_H + cell * rows as u32), |root| {
        let body = root.titled(title, title_style())?;
        let (grid, legend) = body.split_horizontally(width - LEGEND_W);
        let span = frames
            .iter()
            .flat_map(|f| f.a.iter().chain(&f.b).flatten())
            .fold(
                (
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                    f64::INFINITY,
                    f64::NEG_INFINITY,
                ),
                |s, p| (s.0.min(p.0), s.1.max(p.0), s.2.min(p.1), s.3.max(p.1)),
            );
        let half = ((span.1 - span.0).max(span.3 - span.2) / 2.0).max(0.05) * 1.1;
        for (f, area) in frames.iter().zip(grid.split_evenly((rows, cols))) {
            let pts = f.a.iter().chain(&f.b).flatten();
            let n = pts.clone().count().max(1) as f64;
            let cx = pts.clone().map(|p| p.0).sum::<f64>() / n;
            let cy = (span.2 + span.3) / 2.0;
            let mut chart = ChartBuilder::on(&area)
                .caption(&f.title, (FONT, 15))
                .margin(6)
                .x_label_area_size(36)
                .y_label_area_size(50)
                .build_cartesian_2d(cx - half..cx + half, cy - half..cy + half)?;
            chart
                .configure_mesh()
                .x_desc(x_label)
                .y_desc(y_label)
                .x_labels(4)
                .y_labels(4)
                .label_style((FONT, 12))
                .axis_desc_style((FONT, 13))
                .draw()?;
            let col_a = RGBColor(255, 127, 14);
            for line in &f.a {
                chart.draw_series(LineSeries::new(line.clone(), col_a.stroke_width(2)))?;
            }
            for line in &f.b {
                chart.draw_series(LineSeries::new(line.clone(), STANCE.stroke_width(3)))?;
            }
        }
        draw_legend(
            &legend,
            &[
                (label_a.to_string(), Swatch::Line(RGBColor(255, 127, 14))),
                (label_b.to_string(), Swatch::Line(STANCE)),
            ],
            45,
        )
    })
}

/// One chart of [`grouped_bars`]: `values[group][category]` (NaN: no bar).
#[derive(Debug, Clone, Default)]
pub struct BarPanel {
    pub title: String,
    pub y_label: String,
    pub values: Vec<Vec<f64>>,
}

/// Grouped bar charts, one panel each: categories along x (named), one bar per group.
pub fn grouped_bars(
    path: &Path,
    title: &str,
    categories: &[String],
    groups: &[String],
    panels: &[BarPanel],
) -> Result<(), PlotError> {
    let height = TITLE_H + PANEL_H * panels.len().max(1) as u32;
    render(path, (WIDTH, height), |root| {
        let body = root.titled(title, title_style())?;
        for (panel, area) in panels
            .iter()
            .zip(body.split_evenly((panels.len().max(1), 1)))
        {
            let (chart_area, legend) = area.split_horizontally(WIDTH - LEGEND_W);
            let yr = axis_range(
                panel
                    .values
                    .iter()
                    .flatten()
                    .copied()
                    .filter(|v| v.is_finite())
                    .chain([0.0]),
            );
            let n = categories.len().max(1);
            let cats = categories.to_vec();
            let mut chart = ChartBuilder::on(&chart_area)
                .caption(&panel.title, (FONT, 18))
                .margin(8)
                .x_label_area_size(42)
                .y_label_area_size(80)
                .build_cartesian_2d(-0.5f64..(n as f64 - 0.5), yr.0..yr.1)?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(n)
                .x_label_formatter(&|x| {
                    let i = x.round();
                    if (x - i).abs() < 0.01 && i >= 0.0 && (i as usize) < cats.len() {
                        cats[i as usize].clone()
                    } else {
                        String::new()
                    }
                })
                .y_desc(panel.y_label.as_str())
                .y_label_formatter(&tick_format(yr))
                .label_style((FONT, 13))
                .axis_desc_style((FONT, 15))
                .draw()?;
            let g = groups.len().max(1) as f64;
            let w = 0.8 / g;
            let mut entries = Vec::new();
            for (gi, name) in groups.iter().enumerate() {
                let color = palette(gi);
                let bars = panel
                    .values
                    .get(gi)
                    .into_iter()
                    .flatten()
                    .enumerate()
                    .filter(|(_, v)| v.is_finite())
                    .map(|(ci, v)| {
                        let x0 = ci as f64 - 0.4 + gi as f64 * w;
                        Rectangle::new([(x0, 0.0), (x0 + w * 0.9, *v)], color.filled())
                    });
                chart.draw_series(bars)?;
                entries.push((name.clone(), Swatch::Bar(color)));
            }
            draw_legend(&legend, &entries, 36)?;
        }
        Ok(())
    })
}
