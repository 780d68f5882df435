//! The robot and the terrain as the generated MJCF describes them, logged once as static
//! geometry: each geom under its body's entity with its local pose, so that one transform per
//! body and frame moves the robot.

use crate::ops::{Op, Ops, Rgba, Shape};
use mujoco_rs::prelude::*;

/// Entity paths of the truth, the estimate's ghost and the terrain.
pub const ROBOT: &str = "world/robot";
pub const GHOST: &str = "world/estimate";
pub const TERRAIN: &str = "world/terrain";

/// The robot's bodies (all but the world body): MuJoCo id and entity name.
pub fn robot_bodies(model: &MjModel) -> Vec<(usize, String)> {
    (1..model.ffi().nbody as usize)
        .map(|b| {
            let name = model
                .id_to_name(MjtObjBase::mjOBJ_BODY, b)
                .map(str::to_string)
                .unwrap_or_else(|| format!("body_{b}"));
            (b, name)
        })
        .collect()
}

fn geom_name(model: &MjModel, g: usize) -> String {
    model
        .id_to_name(MjtObjBase::mjOBJ_GEOM, g)
        .map(str::to_string)
        .unwrap_or_else(|| format!("geom_{g}"))
}

fn f32x3(v: [f64; 3]) -> [f32; 3] {
    [v[0] as f32, v[1] as f32, v[2] as f32]
}

/// Every geom of the model, static: robot geoms under `world/robot/<body>/<geom>` (and a
/// translucent copy under `world/estimate/…` when `ghost`), world geoms other than the
/// infinite floor under `world/terrain/<geom>` (the viewer draws its own ground grid).
pub fn static_scene(ops: &mut Ops, model: &MjModel, ghost: bool) {
    let bodies = robot_bodies(model);
    let body_name = |b: usize| {
        bodies
            .iter()
            .find(|(id, _)| *id == b)
            .map(|(_, n)| n.clone())
    };
    for g in 0..model.ffi().ngeom as usize {
        let body = model.geom_bodyid()[g] as usize;
        let kind = model.geom_type()[g];
        if body == 0 && kind == MjtGeomBase::mjGEOM_PLANE {
            continue;
        }
        let Some(shape) = shape(model, g, kind) else {
            // Planes on a body and meshes do not occur in the generated models.
            continue;
        };
        let rgba = model.geom_rgba()[g];
        let colour = |a: f32| -> Rgba {
            [
                (rgba[0] * 255.0) as u8,
                (rgba[1] * 255.0) as u8,
                (rgba[2] * 255.0) as u8,
                (a * 255.0) as u8,
            ]
        };
        let mut places = Vec::new();
        match body_name(body) {
            Some(b) => {
                places.push((
                    format!("{ROBOT}/{b}/{}", geom_name(model, g)),
                    colour(rgba[3]),
                ));
                if ghost {
                    places.push((
                        format!("{GHOST}/{b}/{}", geom_name(model, g)),
                        [90, 140, 255, 90],
                    ));
                }
            }
            None => places.push((format!("{TERRAIN}/{}", geom_name(model, g)), colour(1.0))),
        }
        let q = model.geom_quat()[g];
        for (path, colour) in places {
            ops.push(Op::Transform {
                path: path.clone(),
                translation: f32x3(model.geom_pos()[g]),
                quaternion_wxyz: [q[0] as f32, q[1] as f32, q[2] as f32, q[3] as f32],
                is_static: true,
            });
            ops.push(Op::Shape {
                path,
                shape: shape.clone(),
                colour,
            });
        }
    }
}

fn shape(model: &MjModel, g: usize, kind: MjtGeomBase) -> Option<Shape> {
    let size = model.geom_size()[g];
    Some(match kind {
        MjtGeomBase::mjGEOM_SPHERE => Shape::Sphere {
            radius: size[0] as f32,
        },
        MjtGeomBase::mjGEOM_ELLIPSOID => Shape::Ellipsoid {
            half_sizes: f32x3(size),
        },
        MjtGeomBase::mjGEOM_CAPSULE => Shape::Capsule {
            length: 2.0 * size[1] as f32,
            radius: size[0] as f32,
            z_start: -size[1] as f32,
        },
        MjtGeomBase::mjGEOM_CYLINDER => Shape::Cylinder {
            length: 2.0 * size[1] as f32,
            radius: size[0] as f32,
        },
        MjtGeomBase::mjGEOM_BOX => Shape::Box {
            half_sizes: f32x3(size),
        },
        MjtGeomBase::mjGEOM_HFIELD => height_field_mesh(model, model.geom_dataid()[g] as usize),
        _ => return None,
    })
}

/// A height field as a triangle mesh in its geom's frame: MuJoCo's elevation data in [0, 1]
/// scaled by the top height, on a grid spanning ±size_x, ±size_y.
fn height_field_mesh(model: &MjModel, h: usize) -> Shape {
    let [sx, sy, sz, _] = model.hfield_size()[h];
    let rows = model.hfield_nrow()[h] as usize;
    let cols = model.hfield_ncol()[h] as usize;
    let adr = model.hfield_adr()[h] as usize;
    let data = &model.hfield_data()[adr..adr + rows * cols];
    let mut vertices = Vec::with_capacity(rows * cols);
    for r in 0..rows {
        for c in 0..cols {
            let x = -sx + 2.0 * sx * c as f64 / (cols - 1).max(1) as f64;
            let y = -sy + 2.0 * sy * r as f64 / (rows - 1).max(1) as f64;
            vertices.push([x as f32, y as f32, (data[r * cols + c] as f64 * sz) as f32]);
        }
    }
    let mut triangles = Vec::with_capacity(2 * rows * cols);
    for r in 0..rows.saturating_sub(1) {
        for c in 0..cols.saturating_sub(1) {
            let i = (r * cols + c) as u32;
            let (right, up) = (i + 1, i + cols as u32);
            triangles.push([i, right, up + 1]);
            triangles.push([i, up + 1, up]);
        }
    }
    Shape::Mesh {
        vertices,
        triangles,
    }
}
