//! The recording written in this process by Rerun's Rust SDK (feature `sdk`).

use crate::backend::{Backend, Opening};
use crate::ops::{Layout, Op, Rgba, Shape};
use crate::target::{viewer_url, RerunTarget};
use crate::VizError;
use rerun::blueprint::{
    Blueprint, ContainerLike, Horizontal, Spatial3DView, Tabs, TimePanel, TimeSeriesView, Vertical,
};
use rerun::{Color, RecordingStream, RecordingStreamResult};
use std::time::Duration;

pub struct SdkBackend {
    rec: RecordingStream,
    /// A file is complete only when its writer has finished: wait for it.
    flush_blocking: bool,
}

fn colour(c: &Rgba) -> Color {
    Color::from_unmultiplied_rgba(c[0], c[1], c[2], c[3])
}

fn colours(cs: &[Rgba]) -> Vec<Color> {
    cs.iter().map(colour).collect()
}

pub fn blueprint(layout: &Layout) -> Blueprint {
    let series = |v: &crate::ops::SeriesView| -> ContainerLike {
        TimeSeriesView::new(v.name.as_str())
            .with_origin(v.origin.as_str())
            .into()
    };
    let rows: Vec<ContainerLike> = layout
        .rows
        .iter()
        .map(|row| match row.as_slice() {
            [one] => series(one),
            many => Tabs::new(many.iter().map(series)).into(),
        })
        .collect();
    let scene: ContainerLike = Spatial3DView::new(layout.scene_name.as_str())
        .with_origin(layout.scene_origin.as_str())
        .into();
    let plots = Vertical::new(rows).with_row_shares(layout.row_shares.clone());
    Blueprint::new(Horizontal::new([scene, plots.into()]).with_column_shares(layout.column_shares))
        .with_time_panel(TimePanel::new().with_timeline(layout.timeline.as_str()))
}

impl SdkBackend {
    pub fn open(o: &Opening) -> Result<Self, VizError> {
        let builder = rerun::RecordingStreamBuilder::new(crate::APPLICATION_ID)
            .recording_name(o.recording_name)
            .with_blueprint(blueprint(o.layout));
        let rec = match o.target {
            RerunTarget::File(path) => builder.save(path),
            RerunTarget::Connect(address) => builder.connect_grpc_opts(viewer_url(address)?.0),
            RerunTarget::Serve(port) => builder.serve_grpc_opts(
                "0.0.0.0",
                *port,
                rerun::ServerOptions {
                    memory_limit: rerun::MemoryLimit::from_fraction_of_total(0.25),
                    ..Default::default()
                },
            ),
        }
        .map_err(|e| VizError::Target(format!("cannot open the Rerun recording: {e}")))?;
        rec.log_static("world", &rerun::ViewCoordinates::RIGHT_HAND_Z_UP())
            .map_err(|e| VizError::Target(format!("cannot log the scene: {e}")))?;
        Ok(SdkBackend {
            rec,
            flush_blocking: matches!(o.target, RerunTarget::File(_)),
        })
    }

    fn one(&mut self, op: &Op) -> RecordingStreamResult<()> {
        let rec = &self.rec;
        match op {
            Op::Time { t } => {
                rec.set_duration_secs(crate::ops::TIMELINE, *t);
                Ok(())
            }
            Op::Transform {
                path,
                translation,
                quaternion_wxyz: q,
                is_static,
            } => {
                let tf = rerun::Transform3D::from_translation(*translation)
                    .with_quaternion(rerun::Quaternion::from_wxyz(*q));
                if *is_static {
                    rec.log_static(path.as_str(), &tf)
                } else {
                    rec.log(path.as_str(), &tf)
                }
            }
            Op::Shape {
                path,
                shape,
                colour: c,
            } => log_shape(rec, path, shape, colour(c)),
            Op::Points {
                path,
                points,
                colours: cs,
                radius,
            } => rec.log(
                path.as_str(),
                &rerun::Points3D::new(points.iter().copied())
                    .with_colors(colours(cs))
                    .with_radii([*radius]),
            ),
            Op::Strips {
                path,
                strips,
                colours: cs,
                radius,
                labels,
            } => {
                let mut s = rerun::LineStrips3D::new(strips.iter().cloned())
                    .with_colors(colours(cs))
                    .with_radii([*radius]);
                if !labels.is_empty() {
                    s = s.with_labels(labels.iter().map(String::as_str));
                }
                rec.log(path.as_str(), &s)
            }
            Op::Arrows {
                path,
                origins,
                vectors,
                colour: c,
                radius,
            } => rec.log(
                path.as_str(),
                &rerun::Arrows3D::from_vectors(vectors.iter().copied())
                    .with_origins(origins.iter().copied())
                    .with_colors([colour(c)])
                    .with_radii([*radius]),
            ),
            Op::Scalar { path, value } => rec.log(path.as_str(), &rerun::Scalars::single(*value)),
            Op::SeriesStyle {
                path,
                name,
                colour: c,
            } => rec.log_static(
                path.as_str(),
                &rerun::SeriesLines::new()
                    .with_names([name.as_str()])
                    .with_colors([colour(c)]),
            ),
        }
    }
}

fn log_shape(
    rec: &RecordingStream,
    path: &str,
    shape: &Shape,
    c: Color,
) -> RecordingStreamResult<()> {
    let solid = rerun::FillMode::Solid;
    match shape {
        Shape::Sphere { radius } => rec.log_static(
            path,
            &rerun::Ellipsoids3D::from_radii([*radius])
                .with_colors([c])
                .with_fill_mode(solid),
        ),
        Shape::Ellipsoid { half_sizes } => rec.log_static(
            path,
            &rerun::Ellipsoids3D::from_half_sizes([*half_sizes])
                .with_colors([c])
                .with_fill_mode(solid),
        ),
        Shape::Capsule {
            length,
            radius,
            z_start,
        } => rec.log_static(
            path,
            &rerun::Capsules3D::from_lengths_and_radii([*length], [*radius])
                .with_translations([[0.0, 0.0, *z_start]])
                .with_colors([c])
                .with_fill_mode(solid),
        ),
        Shape::Cylinder { length, radius } => rec.log_static(
            path,
            &rerun::Cylinders3D::from_lengths_and_radii([*length], [*radius])
                .with_colors([c])
                .with_fill_mode(solid),
        ),
        Shape::Box { half_sizes } => rec.log_static(
            path,
            &rerun::Boxes3D::from_half_sizes([*half_sizes])
                .with_colors([c])
                .with_fill_mode(solid),
        ),
        Shape::Mesh {
            vertices,
            triangles,
        } => rec.log_static(
            path,
            &rerun::Mesh3D::new(vertices.iter().copied())
                .with_triangle_indices(triangles.iter().copied())
                .with_albedo_factor(c.0),
        ),
    }
}

impl Backend for SdkBackend {
    fn log(&mut self, ops: &[Op]) -> usize {
        ops.iter().filter(|op| self.one(op).is_err()).count()
    }

    fn finish(self: Box<Self>) -> (bool, usize) {
        let flushed = if self.flush_blocking {
            let ok = self.rec.flush_blocking().is_ok();
            drop(self.rec);
            ok
        } else {
            let ok = self.rec.flush_with_timeout(Duration::from_secs(5)).is_ok();
            let rec = self.rec;
            if ok {
                // Hang up now: a viewer or server that answered sees the stream end.
                drop(rec);
            } else {
                // Dropping a stream to a viewer that never answers waits for it forever
                // (0.36.3): what could be sent was, so let a thread of its own do that.
                let _ = std::thread::Builder::new()
                    .name("eemp-rerun-close".into())
                    .spawn(move || drop(rec));
            }
            ok
        };
        (flushed, 0)
    }
}
