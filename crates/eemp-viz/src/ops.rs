//! What a recording is made of, independent of the library that writes it: the writer turns
//! the loop's frames into these operations, and a backend (Rerun's Rust SDK, or Python's
//! `rerun-sdk` through a pipe) turns each into one log call. Keeping the geometry here means
//! both backends draw exactly the same planner (one place computes ellipses, paths and cones).

use serde::Serialize;

/// The simulation-time timeline every entity is logged on.
pub const TIMELINE: &str = "sim_time";

/// An sRGB colour with alpha, 0–255 each.
pub type Rgba = [u8; 4];

pub const fn rgb(r: u8, g: u8, b: u8) -> Rgba {
    [r, g, b, 255]
}

/// A solid shape drawn at its entity's origin (the static scene's geoms).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum Shape {
    Sphere {
        radius: f32,
    },
    Ellipsoid {
        half_sizes: [f32; 3],
    },
    /// Along z from `z_start` (Rerun's capsules start at their origin, MuJoCo's are centred).
    Capsule {
        length: f32,
        radius: f32,
        z_start: f32,
    },
    /// Centred on its origin, along z.
    Cylinder {
        length: f32,
        radius: f32,
    },
    Box {
        half_sizes: [f32; 3],
    },
    Mesh {
        vertices: Vec<[f32; 3]>,
        triangles: Vec<[u32; 3]>,
    },
}

/// One log call. Entity paths are Rerun's (`world/robot/trunk`, `plots/velocity/vx/actual`).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "op", rename_all = "snake_case")]
pub enum Op {
    /// The simulation time the following operations are logged at, s.
    Time { t: f64 },
    /// The entity's pose in its parent's frame (static: once, for all time).
    Transform {
        path: String,
        translation: [f32; 3],
        quaternion_wxyz: [f32; 4],
        #[serde(rename = "static")]
        is_static: bool,
    },
    /// Static solid geometry.
    Shape {
        path: String,
        shape: Shape,
        colour: Rgba,
    },
    /// Points of one radius; one colour for all or one per point.
    Points {
        path: String,
        points: Vec<[f32; 3]>,
        colours: Vec<Rgba>,
        radius: f32,
    },
    /// Polylines; one colour for all or one per strip; labels empty or one per strip.
    Strips {
        path: String,
        strips: Vec<Vec<[f32; 3]>>,
        colours: Vec<Rgba>,
        radius: f32,
        labels: Vec<String>,
    },
    Arrows {
        path: String,
        origins: Vec<[f32; 3]>,
        vectors: Vec<[f32; 3]>,
        colour: Rgba,
        radius: f32,
    },
    /// One value of a time series (non-finite values are not logged).
    Scalar { path: String, value: f64 },
    /// A series' legend name and colour (static).
    SeriesStyle {
        path: String,
        name: String,
        colour: Rgba,
    },
}

/// Operations in the order they are to be logged.
#[derive(Debug, Default)]
pub struct Ops(pub Vec<Op>);

impl Ops {
    pub fn time(&mut self, t: f64) {
        self.0.push(Op::Time { t });
    }

    pub fn scalar(&mut self, path: impl Into<String>, value: f64) {
        if value.is_finite() {
            self.0.push(Op::Scalar {
                path: path.into(),
                value,
            });
        }
    }

    pub fn push(&mut self, op: Op) {
        self.0.push(op);
    }
}

/// The layout a recording opens with: the 3-D scene beside rows of time-series views (a row
/// of several views becomes tabs). Both backends build their blueprint from it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Layout {
    pub scene_name: String,
    /// The entity the 3-D view is rooted at.
    pub scene_origin: String,
    pub rows: Vec<Vec<SeriesView>>,
    /// Heights of the rows, relative.
    pub row_shares: Vec<f32>,
    /// Widths of the scene and the plots, relative.
    pub column_shares: [f32; 2],
    /// The timeline the time panel shows.
    pub timeline: String,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct SeriesView {
    pub name: String,
    pub origin: String,
}
