//! A robot read from its own MuJoCo model: a short binding file (`robots/<name>.toml` with a
//! `[model]` table) names the MJCF, the standing pose and what changes for torque control; the
//! legs, their geometry, masses, inertias, joint ranges and torque limits are read from the model
//! as MuJoCo compiles it. Nothing is typed twice.
//!
//! What the loader changes in the model, and why (all in [`bind`]):
//! - mesh geoms that do not collide, textures and materials are removed: the visual meshes are
//!   not vendored (masses come from `<inertial>`); a colliding mesh stays, with its file;
//! - its actuators are replaced by one torque `motor` per leg joint, limited to the model's
//!   torque limits (the controllers command torques);
//! - joint damping, armature and friction loss become the binding's (a model's damping is often
//!   a tuning for its position servos);
//! - its sensors and keyframes are removed (the scene has the IMU; the runs set the poses);
//! - its geoms' contact priority is 0, so the floor's and the terrain's friction, contact
//!   dimension and softness govern every contact, as for the typed robots;
//! - the trunk, legs, joints, feet and motors take the project's names (`trunk`, `FL_hip_joint`,
//!   `FL_foot`, …), and an IMU site sits at the trunk's origin.
//!
//! The floor, terrain, contact options and sensors are the scene's, as for every robot
//! (`mjcf`).

use eemp_core::config_error::ConfigError;
use eemp_core::energy::MotorConfig;
use eemp_core::leg::{Leg, LegMap};
use eemp_core::leg_geometry::LegGeometry;
use eemp_core::robot::{
    fnv1a64, ControlDefaults, LegConfig, LinkConfig, LinkInertial, ModelDescription, ModelEdits,
    RobotConfig, SdkConfig, SimulationConfig, TrunkConfig,
};
use mujoco_rs::prelude::*;
use mujoco_rs::wrappers::mj_editing::SpecObject;
use nalgebra::{Matrix3, Vector3};
use serde::Deserialize;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// A robot file that binds the robot to its MuJoCo model.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RobotBinding {
    pub name: String,
    pub model: ModelBinding,
    pub simulation: SimulationConfig,
    #[serde(default)]
    pub sdk: SdkConfig,
    #[serde(default)]
    pub control: ControlDefaults,
    #[serde(default)]
    pub motor: Option<MotorConfig>,
}

/// `[model]`: which model, and what torque control changes in it.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelBinding {
    /// The MJCF, relative to the binding file.
    pub file: PathBuf,
    /// Where the model comes from and under which license.
    pub source: String,
    /// Standing joint angles (abduction, thigh, calf) of every leg, rad.
    pub standing_pose_rad: [f64; 3],
    /// Joint damping (abduction, thigh, calf), N·m·s/rad, replacing the model's.
    pub damping: [f64; 3],
    /// Rotor armature (abduction, thigh, calf), kg·m²; the model's without it.
    #[serde(default)]
    pub armature_kg_m2: Option<[f64; 3]>,
    /// Dry friction (abduction, thigh, calf), N·m; the model's without it.
    #[serde(default)]
    pub frictionloss_nm: Option<[f64; 3]>,
    /// Torque limits (abduction, thigh, calf), N·m, where the model gives none (a motor's
    /// `ctrlrange`, an actuator's `forcerange` or a joint's `actuatorfrcrange`).
    #[serde(default)]
    pub torque_limit_nm: Option<[f64; 3]>,
}

fn invalid(name: impl Into<String>, message: impl Into<String>) -> ConfigError {
    ConfigError::Invalid {
        name: name.into(),
        message: message.into(),
    }
}

/// Loads any robot file: one typed into its file ([`RobotConfig::load`]) or one bound to its
/// own MuJoCo model ([`bind`]).
pub fn load_robot(path: &Path) -> Result<RobotConfig, ConfigError> {
    let table: toml::Table = eemp_core::config_error::load_toml(path)?;
    if !table.contains_key("model") {
        return RobotConfig::load(path);
    }
    let binding: RobotBinding = eemp_core::config_error::load_toml(path)?;
    let dir = path.parent().unwrap_or(Path::new("."));
    bind(&binding, dir).map_err(|e| match e {
        ConfigError::Invalid { name, message } => ConfigError::Invalid {
            name: format!("{} ({name})", path.display()),
            message,
        },
        other => other,
    })
}

/// [`load_robot`], or the shipped A1 without a path (what every `--robot` / `robot=` means).
pub fn load_robot_or_a1(path: Option<&Path>) -> Result<RobotConfig, ConfigError> {
    match path {
        Some(p) => load_robot(p),
        None => Ok(RobotConfig::a1()),
    }
}

const JOINTS: [&str; 3] = ["hip", "thigh", "calf"];

/// One leg as found in the compiled model: its three hinge joints (ids, trunk to foot), the
/// foot geom and the bodies that move with each joint.
struct FoundLeg {
    joints: [usize; 3],
    foot_geom: usize,
    link_bodies: [Vec<usize>; 3],
}

/// Compiles `binding`'s model with the edits the module doc lists and reads the robot from it.
pub fn bind(binding: &RobotBinding, dir: &Path) -> Result<RobotConfig, ConfigError> {
    let file = dir.join(&binding.model.file);
    let source = std::fs::canonicalize(&file)
        .map_err(|e| invalid("model.file", format!("{}: {e}", file.display())))?;
    let m = &binding.model;
    let edits = ModelEdits {
        damping_n_m_s_per_rad: m.damping,
        armature_kg_m2: m.armature_kg_m2,
        frictionloss_nm: m.frictionloss_nm,
        torque_limit_nm: m.torque_limit_nm,
    };
    let (mut spec, limits) = edited_spec(&source, &edits)?;
    let model = spec
        .compile()
        .map_err(|e| invalid("model.file", format!("{}: {e}", source.display())))?;
    describe(binding, source, edits, &model, &limits)
}

/// The robot's model as the simulation runs it: `source` parsed, the visual meshes stripped,
/// the project's names, motors and passive terms put in (the module doc); with the torque
/// limits (abduction, thigh, calf) its motors were given.
pub fn edited_spec(source: &Path, edits: &ModelEdits) -> Result<(MjSpec, [f64; 3]), ConfigError> {
    let model_err =
        |e: &dyn std::fmt::Display| invalid("model.file", format!("{}: {e}", source.display()));
    let mut spec = MjSpec::from_xml(source).map_err(|e| model_err(&e))?;
    strip_visual_meshes(&mut spec, source.parent().unwrap_or(Path::new(".")))
        .map_err(|m| invalid("model.file", m))?;
    // Geoms are found again by name after the first compile (the foot takes the project's
    // name); Menagerie leaves its collision geoms unnamed.
    for (i, g) in spec.geom_iter_mut().enumerate() {
        if g.name().is_empty() {
            g.set_name(&format!("model_geom_{i}"))
                .map_err(|e| invalid("model.file", e.to_string()))?;
        }
    }
    // The model as shipped (less its visuals): its actuators say the torque limits.
    let original = spec.compile().map_err(|e| model_err(&e))?;
    let (trunk, legs) = find_legs(&original)?;
    let limits = torque_limits(&original, &legs, edits.torque_limit_nm)?;
    rename_and_motorise(&mut spec, &original, trunk, &legs, edits, &limits)
        .map_err(|m| invalid("model.file", m))?;
    Ok((spec, limits))
}

/// Removes the mesh geoms that do not collide (visuals), the meshes no geom uses any more,
/// textures and materials; a colliding mesh stays, its file found from the model's folder.
fn strip_visual_meshes(spec: &mut MjSpec, model_dir: &Path) -> Result<(), String> {
    while let Some(geom) = spec
        .geom_iter_mut()
        .find(|g| g.type_() == MjtGeomBase::mjGEOM_MESH && g.contype() == 0 && g.conaffinity() == 0)
    {
        // SAFETY: the geom is deleted once; no handle outlives the call.
        unsafe { geom.delete() }.map_err(|e| e.to_string())?;
    }
    let used: Vec<String> = spec
        .geom_iter()
        .filter(|g| g.type_() == MjtGeomBase::mjGEOM_MESH)
        .map(|g| g.meshname().to_string())
        .collect();
    let mesh_name = |name: &str, file: &str| -> String {
        match name {
            "" => Path::new(file)
                .file_stem()
                .map(|s| s.to_string_lossy().into_owned())
                .unwrap_or_default(),
            n => n.to_string(),
        }
    };
    while let Some(mesh) = spec
        .mesh_iter_mut()
        .find(|m| !used.contains(&mesh_name(m.name(), m.file())))
    {
        // SAFETY: as above.
        unsafe { mesh.delete() }.map_err(|e| e.to_string())?;
    }
    let mesh_dir = model_dir.join(spec.compiler().meshdir());
    for mesh in spec.mesh_iter_mut() {
        let file = mesh_dir.join(mesh.file());
        let file = std::fs::canonicalize(&file).map_err(|e| {
            format!(
                "mesh {:?} collides but its file {} cannot be read: {e}",
                mesh_name(mesh.name(), mesh.file()),
                file.display()
            )
        })?;
        mesh.set_file(&file.to_string_lossy());
    }
    spec.compiler_mut().set_meshdir("");
    for g in spec.geom_iter_mut() {
        g.set_material("");
    }
    while let Some(m) = spec.material_iter_mut().next() {
        // SAFETY: as above.
        unsafe { m.delete() }.map_err(|e| e.to_string())?;
    }
    while let Some(t) = spec.texture_iter_mut().next() {
        // SAFETY: as above.
        unsafe { t.delete() }.map_err(|e| e.to_string())?;
    }
    // Lights and cameras track bodies by the names the loader changes; the scene has its own.
    while let Some(l) = spec.light_iter_mut().next() {
        // SAFETY: as above.
        unsafe { l.delete() }.map_err(|e| e.to_string())?;
    }
    while let Some(c) = spec.camera_iter_mut().next() {
        // SAFETY: as above.
        unsafe { c.delete() }.map_err(|e| e.to_string())?;
    }
    Ok(())
}

fn name_of(model: &MjModel, kind: MjtObjBase, id: usize) -> String {
    model.id_to_name(kind, id).unwrap_or_default().to_string()
}

/// The trunk (the body of the free joint) and its four legs: every chain of three hinge joints
/// from a child of the trunk to a sphere foot.
fn find_legs(model: &MjModel) -> Result<(usize, LegMap<FoundLeg>), ConfigError> {
    let jnt_type = model.jnt_type();
    let free: Vec<usize> = (0..jnt_type.len())
        .filter(|&j| jnt_type[j] == MjtJoint::mjJNT_FREE)
        .collect();
    let [free] = free[..] else {
        return Err(invalid(
            "model",
            format!(
                "needs exactly one free joint (the trunk's), found {}",
                free.len()
            ),
        ));
    };
    let trunk = model.jnt_bodyid()[free] as usize;
    let parent = model.body_parentid();
    // The hinge joints on the path trunk → body, trunk first.
    let hinges_to = |mut b: usize| -> Option<Vec<usize>> {
        let mut chain = Vec::new();
        while b != trunk {
            if b == 0 {
                return None;
            }
            let (adr, num) = (model.body_jntadr()[b], model.body_jntnum()[b]);
            for j in (adr..adr + num).rev() {
                let j = j as usize;
                if jnt_type[j] != MjtJoint::mjJNT_HINGE {
                    return None;
                }
                chain.push(j);
            }
            b = parent[b] as usize;
        }
        chain.reverse();
        Some(chain)
    };
    // Feet: sphere geoms at the end of three hinges; one per abduction joint.
    let mut feet: Vec<(usize, [usize; 3])> = Vec::new();
    for g in 0..model.ffi().ngeom as usize {
        if model.geom_type()[g] != MjtGeomBase::mjGEOM_SPHERE {
            continue;
        }
        let Some(chain) = hinges_to(model.geom_bodyid()[g] as usize) else {
            continue;
        };
        if let [a, b, c] = chain[..] {
            if let Some(f) = feet.iter_mut().find(|f| f.1[0] == a) {
                return Err(invalid(
                    "model",
                    format!(
                        "the leg of joint {:?} has two sphere feet ({:?} and {:?})",
                        name_of(model, MjtObjBase::mjOBJ_JOINT, a),
                        name_of(model, MjtObjBase::mjOBJ_GEOM, f.0),
                        name_of(model, MjtObjBase::mjOBJ_GEOM, g)
                    ),
                ));
            }
            feet.push((g, [a, b, c]));
        }
    }
    // A leg without a foot, or with other than three hinges, is named.
    for (b, &p) in parent.iter().enumerate() {
        if p as usize == trunk && b != trunk && model.body_jntnum()[b] > 0 {
            let first = model.body_jntadr()[b] as usize;
            if !feet.iter().any(|f| f.1[0] == first) {
                return Err(invalid(
                    "model",
                    format!(
                        "the leg from body {:?} has no sphere foot at the end of three hinge \
                         joints (a foot point and a three-joint leg are needed)",
                        name_of(model, MjtObjBase::mjOBJ_BODY, b)
                    ),
                ));
            }
        }
    }
    if feet.len() != 4 {
        return Err(invalid(
            "model",
            format!(
                "needs four legs of three hinge joints ending in a sphere foot, found {}",
                feet.len()
            ),
        ));
    }
    let mut data = MjData::new(model);
    data.forward();
    let (p_trunk, r_trunk) = body_frame(&data, trunk);
    let mut found: [Option<FoundLeg>; 4] = [None, None, None, None];
    for (foot_geom, joints) in feet {
        let anchor = r_trunk.transpose() * (Vector3::from(data.xanchor()[joints[0]]) - p_trunk);
        let leg = match (anchor.x > 0.0, anchor.y > 0.0) {
            (true, false) => Leg::FrontRight,
            (true, true) => Leg::FrontLeft,
            (false, false) => Leg::RearRight,
            (false, true) => Leg::RearLeft,
        };
        if found[leg.index()].is_some() {
            return Err(invalid(
                "model",
                format!(
                    "two legs' abduction joints sit in the {leg:?} quadrant of the trunk (joint {:?})",
                    name_of(model, MjtObjBase::mjOBJ_JOINT, joints[0])
                ),
            ));
        }
        let mut link_bodies: [Vec<usize>; 3] = Default::default();
        for b in 0..model.ffi().nbody as usize {
            if let Some(chain) = hinges_to(b) {
                if !chain.is_empty() && chain[0] == joints[0] {
                    link_bodies[chain.len().min(3) - 1].push(b);
                }
            }
        }
        found[leg.index()] = Some(FoundLeg {
            joints,
            foot_geom,
            link_bodies,
        });
    }
    let legs = LegMap(found.map(|f| f.expect("four legs in four quadrants")));
    Ok((trunk, legs))
}

fn body_frame(data: &MjData<&MjModel>, b: usize) -> (Vector3<f64>, Matrix3<f64>) {
    let m = data.xmat()[b];
    (
        Vector3::from(data.xpos()[b]),
        Matrix3::new(m[0], m[1], m[2], m[3], m[4], m[5], m[6], m[7], m[8]),
    )
}

/// Per joint kind (abduction, thigh, calf), the smallest torque limit over the legs: a motor's
/// control range times its gear, an actuator's force range, a joint's actuator force range, or
/// the binding's.
fn torque_limits(
    model: &MjModel,
    legs: &LegMap<FoundLeg>,
    from_binding: Option<[f64; 3]>,
) -> Result<[f64; 3], ConfigError> {
    if let Some(l) = from_binding {
        return Ok(l);
    }
    let mut limits = [f64::INFINITY; 3];
    for leg in Leg::ALL {
        for (k, &j) in legs[leg].joints.iter().enumerate() {
            let mut limit = None;
            if model.jnt_actfrclimited()[j] {
                let r = model.jnt_actfrcrange()[j];
                limit = Some(r[1].min(-r[0]));
            }
            for a in 0..model.ffi().nu as usize {
                if model.actuator_trntype()[a] != MjtTrn::mjTRN_JOINT
                    || model.actuator_trnid()[a][0] as usize != j
                {
                    continue;
                }
                let gear = model.actuator_gear()[a][0].abs();
                if model.actuator_forcelimited()[a] {
                    let r = model.actuator_forcerange()[a];
                    limit = Some(r[1].min(-r[0]));
                } else if model.actuator_ctrllimited()[a]
                    && model.actuator_biastype()[a] == MjtBias::mjBIAS_NONE
                {
                    let r = model.actuator_ctrlrange()[a];
                    limit = Some(r[1].min(-r[0]) * gear * model.actuator_gainprm()[a][0].abs());
                }
            }
            let Some(l) = limit.filter(|l| l.is_finite() && *l > 0.0) else {
                return Err(invalid(
                    "model.torque_limit_nm",
                    format!(
                        "joint {:?} of leg {leg:?} has no torque limit in the model (a motor's \
                         ctrlrange, a forcerange or an actuatorfrcrange): give one in the binding",
                        name_of(model, MjtObjBase::mjOBJ_JOINT, j)
                    ),
                ));
            };
            limits[k] = limits[k].min(l);
        }
    }
    Ok(limits)
}

/// Gives the trunk, legs, feet and motors the project's names, adds the IMU and foot sites,
/// replaces the actuators by motors and sets the binding's passive terms.
fn rename_and_motorise(
    spec: &mut MjSpec,
    model: &MjModel,
    trunk: usize,
    legs: &LegMap<FoundLeg>,
    edits: &ModelEdits,
    limits: &[f64; 3],
) -> Result<(), String> {
    let named = |kind: MjtObjBase, id: usize| -> Result<String, String> {
        let n = name_of(model, kind, id);
        if n.is_empty() {
            Err(format!(
                "{kind:?} {id} of a leg or the trunk has no name: name it in the model"
            ))
        } else {
            Ok(n)
        }
    };
    // Names first taken out of the way, so a model's own `FL_foot` cannot collide.
    let mut renames: Vec<(MjtObjBase, String, String)> = Vec::new();
    renames.push((
        MjtObjBase::mjOBJ_BODY,
        named(MjtObjBase::mjOBJ_BODY, trunk)?,
        "trunk".into(),
    ));
    for leg in Leg::ALL {
        let n = leg.short_name();
        let f = &legs[leg];
        for (k, &j) in f.joints.iter().enumerate() {
            renames.push((
                MjtObjBase::mjOBJ_JOINT,
                named(MjtObjBase::mjOBJ_JOINT, j)?,
                format!("{n}_{}_joint", JOINTS[k]),
            ));
            let body = model.jnt_bodyid()[j] as usize;
            renames.push((
                MjtObjBase::mjOBJ_BODY,
                named(MjtObjBase::mjOBJ_BODY, body)?,
                format!("{n}_{}", JOINTS[k]),
            ));
        }
        renames.push((
            MjtObjBase::mjOBJ_GEOM,
            named(MjtObjBase::mjOBJ_GEOM, f.foot_geom)?,
            format!("{n}_foot"),
        ));
    }
    for (i, (kind, from, _)) in renames.iter().enumerate() {
        set_name(spec, *kind, from, &format!("__eemp_{i}"))?;
    }
    // Contact exclusions name bodies: they follow the renames.
    for exclude in spec.exclude_iter_mut() {
        for (kind, from, to) in &renames {
            if *kind != MjtObjBase::mjOBJ_BODY {
                continue;
            }
            if exclude.bodyname1() == from.as_str() {
                exclude.set_bodyname1(&format!("__eemp_to_{to}"));
            }
            if exclude.bodyname2() == from.as_str() {
                exclude.set_bodyname2(&format!("__eemp_to_{to}"));
            }
        }
        let (a, b) = (
            exclude.bodyname1().to_string(),
            exclude.bodyname2().to_string(),
        );
        exclude.set_bodyname1(a.trim_start_matches("__eemp_to_"));
        exclude.set_bodyname2(b.trim_start_matches("__eemp_to_"));
    }
    for (i, (kind, _, to)) in renames.iter().enumerate() {
        set_name(spec, *kind, &format!("__eemp_{i}"), to)?;
    }
    // The model's own IMU site keeps its place under another name; the scene's sits at the
    // trunk's origin, where the estimator assumes it.
    if let Some(site) = spec.site_mut("imu") {
        site.set_name("model_imu").map_err(|e| e.to_string())?;
    }
    // The contact is the scene's: the floor's and the terrain's priority must win. A model's own
    // priority mixes its geoms' parameters with the floor's (equal priorities take the larger
    // friction and contact dimension and average solref/solimp), so a slippery floor would keep
    // the feet's own friction.
    for g in spec.geom_iter_mut() {
        g.set_priority(0);
    }
    let mut added_trunk_box = false;
    {
        let body = spec.body_mut("trunk").ok_or("trunk body lost")?;
        body.add_site().with_name("imu");
        // The trunk's collision geom the falls of learned controllers are told by: its
        // largest colliding primitive.
        let mut best: Option<(f64, usize)> = None;
        for (i, g) in body.geom_iter(false).enumerate() {
            if g.contype() != 0 || g.conaffinity() != 0 {
                let s = g.size();
                let v = s[0].max(1e-9) * s[1].max(1e-9) * s[2].max(1e-9);
                if best.is_none_or(|(bv, _)| v > bv) {
                    best = Some((v, i));
                }
            }
        }
        match best {
            Some((_, i)) => {
                let geom = body.geom_iter_mut(false).nth(i).ok_or("trunk geom lost")?;
                geom.set_name("trunk_geom").map_err(|e| e.to_string())?;
            }
            // A trunk that collides with nothing would sink through the floor in a fall: it
            // gets its inertia's box (the uniform box of its mass and principal moments),
            // massless, as its collision shape, kept off the legs (below) as the model had it.
            None => {
                let i = model.body_inertia()[trunk];
                let m = model.body_mass()[trunk];
                let half = |a: f64, b: f64, c: f64| (1.5 * (b + c - a).max(1e-9) / m).sqrt();
                let size = [
                    half(i[0], i[1], i[2]),
                    half(i[1], i[2], i[0]),
                    half(i[2], i[0], i[1]),
                ];
                let ipos = model.body_ipos()[trunk];
                let iquat = model.body_iquat()[trunk];
                let geom = body.add_geom();
                geom.set_name("trunk_geom").map_err(|e| e.to_string())?;
                geom.set_type(MjtGeomBase::mjGEOM_BOX);
                geom.set_contype(1);
                geom.set_conaffinity(1);
                geom.set_mass(0.0);
                geom.set_density(0.0);
                *geom.size_mut() = size;
                *geom.pos_mut() = ipos;
                *geom.quat_mut() = iquat;
                added_trunk_box = true;
            }
        }
    }
    if added_trunk_box {
        for leg in Leg::ALL {
            for link in JOINTS {
                let e = spec.add_exclude();
                e.set_bodyname1("trunk");
                e.set_bodyname2(&format!("{}_{link}", leg.short_name()));
            }
        }
    }
    for leg in Leg::ALL {
        let n = leg.short_name();
        let foot = spec.geom(&format!("{n}_foot")).ok_or("foot geom lost")?;
        let pos = *foot.pos();
        let body = model.geom_bodyid()[legs[leg].foot_geom] as usize;
        let body_name = if body == model.jnt_bodyid()[legs[leg].joints[2]] as usize {
            format!("{n}_calf")
        } else {
            name_of(model, MjtObjBase::mjOBJ_BODY, body)
        };
        let b = spec
            .body_mut(&body_name)
            .ok_or_else(|| format!("the body of foot {n} ({body_name:?}) has no name"))?;
        b.add_site()
            .with_name(&format!("{n}_foot_site"))
            .with_pos(pos);
    }
    // Passive terms of every leg joint.
    let m = edits;
    for leg in Leg::ALL {
        for (k, j) in JOINTS.iter().enumerate() {
            let joint = spec
                .joint_mut(&format!("{}_{j}_joint", leg.short_name()))
                .ok_or("leg joint lost")?;
            let mut damping = *joint.damping();
            damping.fill(0.0);
            damping[0] = m.damping_n_m_s_per_rad[k];
            *joint.damping_mut() = damping;
            if let Some(a) = m.armature_kg_m2 {
                joint.set_armature(a[k]);
            }
            if let Some(f) = m.frictionloss_nm {
                joint.set_frictionloss(f[k]);
            }
        }
    }
    while let Some(a) = spec.actuator_iter_mut().next() {
        // SAFETY: deleted once; no handle outlives the call.
        unsafe { a.delete() }.map_err(|e| e.to_string())?;
    }
    for leg in Leg::ALL {
        let n = leg.short_name();
        for (k, j) in JOINTS.iter().enumerate() {
            let a = spec.add_actuator();
            a.set_name(&format!("{n}_{j}")).map_err(|e| e.to_string())?;
            a.set_trntype(MjtTrn::mjTRN_JOINT);
            a.set_target(&format!("{n}_{j}_joint"));
            a.set_to_motor();
            a.set_ctrllimited(mujoco_rs::wrappers::mj_editing::MjtLimited::mjLIMITED_TRUE);
            *a.ctrlrange_mut() = [-limits[k], limits[k]];
        }
    }
    // The scene's IMU is the one the estimator reads; the model's own sensors go.
    while let Some(x) = spec.sensor_iter_mut().next() {
        // SAFETY: deleted once; no handle outlives the call.
        unsafe { x.delete() }.map_err(|e| e.to_string())?;
    }
    // Keyframes name the model's own initial poses; the walks set theirs.
    while let Some(k) = spec.key_iter_mut().next() {
        // SAFETY: deleted once; no handle outlives the call.
        unsafe { k.delete() }.map_err(|e| e.to_string())?;
    }
    Ok(())
}

/// What the generated models have and a bound model gets here: the project's contact and
/// integration options, the IMU sensors on the trunk's `imu` site, a larger offscreen buffer for
/// videos, and the camera videos follow the robot with (the A1's view scaled by the robot's
/// leg length).
pub fn complete_for_scene(spec: &mut MjSpec, robot: &RobotConfig) -> Result<(), String> {
    let opt = spec.option_mut();
    opt.timestep = robot.simulation.timestep_s;
    opt.integrator = 0; // mjINT_EULER
    opt.cone = 1; // mjCONE_ELLIPTIC
    opt.impratio = 100.0;
    let visual = spec.visual_mut();
    visual.global.offwidth = 1280;
    visual.global.offheight = 720;
    visual.quality.shadowsize = 1024;
    visual.quality.offsamples = 0;
    for (name, kind) in [
        ("imu_quat", MjtSensor::mjSENS_FRAMEQUAT),
        ("imu_gyro", MjtSensor::mjSENS_GYRO),
        ("imu_accel", MjtSensor::mjSENS_ACCELEROMETER),
    ] {
        let sensor = spec.add_sensor();
        sensor.set_name(name).map_err(|e| e.to_string())?;
        sensor.set_type(kind);
        sensor.set_objtype(MjtObjBase::mjOBJ_SITE);
        sensor.set_objname("imu");
    }
    let [l1, l2] = robot.leg_geometry(Leg::FrontLeft).segment_lengths_m();
    let k = (l1 + l2) / 0.4;
    let trunk = spec.body_mut("trunk").ok_or("trunk body lost")?;
    let camera = trunk.add_camera();
    camera.set_name("track").map_err(|e| e.to_string())?;
    camera.set_mode(MjtCamLight::mjCAMLIGHT_TRACKCOM);
    *camera.pos_mut() = [0.4 * k, -1.6 * k, 0.5 * k];
    camera
        .alt_mut()
        .set_xy_axis(&[1.0, 0.25, 0.0, -0.1, 0.3, 1.0]);
    Ok(())
}

/// A motor-strength error: every motor's gain k (MuJoCo's actuator force k·ctrl), as the
/// generated model writes it.
pub fn scale_motor_strength(spec: &mut MjSpec, k: f64) {
    for a in spec.actuator_iter_mut() {
        a.gainprm_mut()[0] = k;
    }
}

fn set_name(spec: &mut MjSpec, kind: MjtObjBase, from: &str, to: &str) -> Result<(), String> {
    let lost = || format!("{kind:?} {from:?} not found in the model's spec");
    match kind {
        MjtObjBase::mjOBJ_BODY => spec.body_mut(from).ok_or_else(lost)?.set_name(to),
        MjtObjBase::mjOBJ_JOINT => spec.joint_mut(from).ok_or_else(lost)?.set_name(to),
        MjtObjBase::mjOBJ_GEOM => spec.geom_mut(from).ok_or_else(lost)?.set_name(to),
        _ => unreachable!("only bodies, joints and geoms are renamed"),
    }
    .map_err(|e| e.to_string())
}

fn inertia6(i: &Matrix3<f64>) -> [f64; 6] {
    [
        i[(0, 0)],
        i[(1, 1)],
        i[(2, 2)],
        i[(0, 1)],
        i[(0, 2)],
        i[(1, 2)],
    ]
}

/// Mass, COM (relative to `origin`) and inertia about the COM of `bodies`, trunk axes.
fn combine(
    data: &MjData<&MjModel>,
    model: &MjModel,
    bodies: &[usize],
    origin: &Vector3<f64>,
    p_trunk: &Vector3<f64>,
    r_trunk: &Matrix3<f64>,
) -> LinkInertial {
    let parts: Vec<(f64, Vector3<f64>, Matrix3<f64>)> = bodies
        .iter()
        .map(|&b| {
            let m = model.body_mass()[b];
            let c = r_trunk.transpose() * (Vector3::from(data.xipos()[b]) - p_trunk) - origin;
            let x = data.ximat()[b];
            let r = r_trunk.transpose()
                * Matrix3::new(x[0], x[1], x[2], x[3], x[4], x[5], x[6], x[7], x[8]);
            let i =
                r * Matrix3::from_diagonal(&Vector3::from(model.body_inertia()[b])) * r.transpose();
            (m, c, i)
        })
        .collect();
    let mass: f64 = parts.iter().map(|p| p.0).sum();
    let com = if mass > 0.0 {
        parts.iter().map(|p| p.1 * p.0).sum::<Vector3<f64>>() / mass
    } else {
        Vector3::zeros()
    };
    let mut inertia = Matrix3::zeros();
    for (m, c, i) in &parts {
        let d = c - com;
        inertia += i + *m * (Matrix3::identity() * d.dot(&d) - d * d.transpose());
    }
    LinkInertial {
        mass_kg: mass,
        com_m: com,
        inertia_kg_m2: inertia,
    }
}

/// Reads the robot from the edited, compiled model.
fn describe(
    binding: &RobotBinding,
    source: PathBuf,
    edits: ModelEdits,
    model: &MjModel,
    limits: &[f64; 3],
) -> Result<RobotConfig, ConfigError> {
    let (trunk, legs) = find_legs(model)?;
    let mut data = MjData::new(model);
    data.forward();
    let (p_trunk, r_trunk) = body_frame(&data, trunk);
    let in_trunk = |p: [f64; 3]| r_trunk.transpose() * (Vector3::from(p) - p_trunk);
    let home = Vector3::from(binding.model.standing_pose_rad);
    let mut geometry: Vec<LegGeometry> = Vec::new();
    let mut links: Vec<[LinkInertial; 3]> = Vec::new();
    let mut ranges: Vec<[[f64; 2]; 3]> = Vec::new();
    for leg in Leg::ALL {
        let f = &legs[leg];
        let anchors = f.joints.map(|j| in_trunk(data.xanchor()[j]));
        let foot = in_trunk(data.geom_xpos()[f.foot_geom]);
        let mut signs = [0.0; 3];
        for (k, &j) in f.joints.iter().enumerate() {
            let axis = r_trunk.transpose() * Vector3::from(data.xaxis()[j]);
            let along = if k == 0 { axis.x } else { axis.y };
            if (along.abs() - 1.0).abs() > 1e-6 {
                return Err(invalid(
                    "model",
                    format!(
                        "joint {:?} of leg {leg:?} turns about {:?} in the trunk frame: a leg's \
                         first axis must be the trunk's ±x, the other two its ±y",
                        name_of(model, MjtObjBase::mjOBJ_JOINT, j),
                        axis.as_slice()
                    ),
                ));
            }
            signs[k] = along.signum();
        }
        let g = LegGeometry::new(
            leg,
            anchors[0],
            anchors[1] - anchors[0],
            anchors[2] - anchors[1],
            foot - anchors[2],
            signs,
            &home,
        )
        .map_err(|e| invalid("model", e.to_string()))?;
        links.push([0, 1, 2].map(|k| {
            combine(
                &data,
                model,
                &f.link_bodies[k],
                &anchors[k],
                &p_trunk,
                &r_trunk,
            )
        }));
        ranges.push(f.joints.map(|j| {
            if model.jnt_limited()[j] {
                model.jnt_range()[j]
            } else {
                [-2.0 * std::f64::consts::PI, 2.0 * std::f64::consts::PI]
            }
        }));
        geometry.push(g);
    }
    // Trunk: every body of the trunk's subtree that no leg joint moves.
    let in_leg: Vec<usize> = Leg::ALL
        .iter()
        .flat_map(|l| legs[*l].link_bodies.iter().flatten().copied())
        .collect();
    let trunk_bodies: Vec<usize> = (1..model.ffi().nbody as usize)
        .filter(|&b| !in_leg.contains(&b) && is_in_subtree(model, b, trunk))
        .collect();
    let t = combine(
        &data,
        model,
        &trunk_bodies,
        &Vector3::zeros(),
        &p_trunk,
        &r_trunk,
    );
    let fl = Leg::FrontLeft.index();
    let foot_radius = model.geom_size()[legs[Leg::FrontLeft].foot_geom][0];
    let [l1, l2] = geometry[fl].segment_lengths_m();
    let range = |k: usize, leg: Leg| ranges[leg.index()][k];
    let link = |k: usize| LinkConfig {
        mass_kg: links[fl][k].mass_kg,
        com_m: links[fl][k].com_m.into(),
        inertia_kg_m2: inertia6(&links[fl][k].inertia_kg_m2),
    };
    let dof = |k: usize, field: &[f64]| {
        field[model.jnt_dofadr()[legs[Leg::FrontLeft].joints[k]] as usize]
    };
    let g_fl = &geometry[fl];
    let leg_config = LegConfig {
        hip_offset_m: [
            g_fl.abduction_anchor_m.x.abs(),
            g_fl.abduction_anchor_m.y.abs(),
        ],
        abduction_to_thigh_m: g_fl.lateral_m().abs(),
        thigh_length_m: l1,
        calf_length_m: l2,
        foot_radius_m: foot_radius,
        abduction_range_rad: range(0, Leg::FrontLeft),
        thigh_range_rad: range(1, Leg::FrontLeft),
        rear_thigh_range_rad: Some(range(1, Leg::RearLeft)),
        calf_range_rad: range(2, Leg::FrontLeft),
        torque_limit_nm: *limits,
        damping: [0, 1, 2].map(|k| dof(k, model.dof_damping())),
        armature_kg_m2: [0, 1, 2].map(|k| dof(k, model.dof_armature())),
        frictionloss_nm: [0, 1, 2].map(|k| dof(k, model.dof_frictionloss())),
        standing_pose_rad: binding.model.standing_pose_rad,
        hip_link: link(0),
        thigh_link: link(1),
        calf_link: link(2),
    };
    let digest = format!("{:016x}", fnv1a64(&model_arrays(model)));
    let trunk_config = TrunkConfig {
        mass_kg: t.mass_kg,
        com_m: t.com_m.into(),
        inertia_kg_m2: inertia6(&t.inertia_kg_m2),
        collision_half_size_m: [0.0; 3],
    };
    let description = ModelDescription {
        source,
        edits,
        legs: LegMap(<[LegGeometry; 4]>::try_from(geometry).expect("four legs")),
        links: LegMap(<[[LinkInertial; 3]; 4]>::try_from(links).expect("four legs")),
        joint_range_rad: LegMap(<[[[f64; 2]; 3]; 4]>::try_from(ranges).expect("four legs")),
        standing_pose_rad: LegMap::splat(home),
        compiled_trunk: trunk_config.clone(),
        digest,
    };
    let robot = RobotConfig {
        name: binding.name.clone(),
        simulation: binding.simulation.clone(),
        trunk: trunk_config.clone(),
        leg: leg_config,
        sdk: binding.sdk.clone(),
        control: binding.control.clone(),
        motor: binding.motor.clone(),
        model: Some(Arc::new(description)),
    };
    robot.validate()?;
    Ok(robot)
}

/// The compiled arrays the simulated dynamics depend on, as text (the robot's id hashes it;
/// no path of this checkout is in it).
fn model_arrays(model: &MjModel) -> String {
    format!(
        "{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}{:?}",
        model.body_parentid(),
        model.body_pos(),
        model.body_quat(),
        model.body_mass(),
        model.body_ipos(),
        model.body_iquat(),
        model.body_inertia(),
        model.jnt_axis(),
        model.jnt_range(),
        model.dof_damping(),
        model.dof_armature(),
        model.dof_frictionloss(),
        model.geom_size(),
        model.actuator_ctrlrange(),
    )
}

fn is_in_subtree(model: &MjModel, mut b: usize, root: usize) -> bool {
    while b != 0 {
        if b == root {
            return true;
        }
        b = model.body_parentid()[b] as usize;
    }
    false
}
