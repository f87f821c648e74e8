//! URDF -> [`LegSpec`], kept apart from the domain model (as openrr/k keeps its conversion
//! apart). One small function per step:
//!
//! 1. `check_nesting`: well-formed XML no deeper than [`MAX_XML_DEPTH`] (roxmltree; a deeper
//!    file would overflow the stack of the URDF deserialiser).
//! 2. `links`: mass properties, finite and of sane magnitude; a link without `<inertial>` has
//!    mass 0 (the URDF spec's default); only the bodies that move (after merging the links
//!    welded to them by fixed joints, as Drake, MuJoCo and Pinocchio do) need mass and inertia.
//! 3. `joints` and `tree_order`: one root, a tree, parent-before-child order.
//! 4. `loop_closure` and `actuator`: the two extension elements.
//! 5. `check_planar` and `check_topology`: the sagittal knee + cylinder loop.
//! 6. `check_moving_bodies`: merged mass and inertia of every moving body.
//! 7. `loop_geometry` and `check_reachable`: the planar loop and its stroke over the knee
//!    range.

use std::collections::HashMap;
use std::path::Path;

use rapier3d_f64::glamx::{DMat3, DQuat, DSymmetricEigen3, DVec3, EulerRot};

use super::error::LegError;
use super::model::{
    joint_origin, ActuatorSpec, CollisionShape, CollisionSpec, JointKind, JointSpec, LegOptions, LegSpec, LinkSpec,
    LoopClosureSpec, LoopGeometry, DEFAULT_KNEE_RANGE_RAD,
};
use super::planar::{Pose2, P2};

mod checks;
use checks::*;

/// Deepest XML nesting accepted (a URDF needs 4 levels).
pub const MAX_XML_DEPTH: usize = 64;
/// Most XML nodes accepted.
const MAX_XML_NODES: u32 = 1_000_000;
/// Largest coordinate accepted in an origin or anchor (m).
const MAX_LENGTH_M: f64 = 100.0;
/// Largest link mass accepted (kg).
const MAX_MASS_KG: f64 = 1e4;
/// Largest inertia entry accepted (kg m^2).
const MAX_INERTIA_KG_M2: f64 = 1e4;
/// Largest joint limit accepted (rad or m).
const MAX_LIMIT: f64 = 1e4;

/// Most links (and most joints) a leg URDF may have: a leg with its exoskeleton has about ten;
/// the cap keeps the per-link chain walks of the loader bounded.
pub const MAX_URDF_LINKS: usize = 256;

/// Parse and validate URDF text into a leg model.
pub fn parse(text: &str, options: &LegOptions) -> Result<LegSpec, LegError> {
    let knee_joint = options.knee_joint.as_str();
    let opts = roxmltree::ParsingOptions { allow_dtd: false, nodes_limit: MAX_XML_NODES, ..Default::default() };
    let doc = roxmltree::Document::parse_with_options(text, opts).map_err(|e| LegError::Xml(e.to_string()))?;
    check_nesting(&doc)?;
    // Count the elements on the parsed tree before urdf-rs builds its own (a 5 MB file of
    // links is refused here, not after a second parse).
    let count = |tag: &str| doc.root_element().children().filter(|n| n.has_tag_name(tag)).count();
    let (nl, nj) = (count("link"), count("joint"));
    if nl > MAX_URDF_LINKS || nj > MAX_URDF_LINKS {
        return Err(LegError::InvalidArgument(format!(
            "{nl} links and {nj} joints: a leg model has at most {MAX_URDF_LINKS} of each"
        )));
    }
    let robot_el = doc.root_element();
    if robot_el.tag_name().name() != "robot" {
        return Err(LegError::Missing { what: "<robot> root element".into() });
    }
    let robot = urdf_rs::read_from_string(text).map_err(|e| LegError::Urdf(e.to_string()))?;
    if robot.links.len() > MAX_URDF_LINKS || robot.joints.len() > MAX_URDF_LINKS {
        return Err(LegError::InvalidArgument(format!(
            "{} links and {} joints: a leg model has at most {MAX_URDF_LINKS} of each",
            robot.links.len(),
            robot.joints.len()
        )));
    }
    if !(options.mass_scale.is_finite() && options.mass_scale > 0.0) {
        return Err(LegError::InvalidArgument(format!("mass scale must be > 0, got {}", options.mass_scale)));
    }
    let mut links = links(&robot)?;
    for l in &mut links {
        l.mass_kg *= options.mass_scale;
        l.inertia_kg_m2 = l.inertia_kg_m2.map(|row| row.map(|x| x * options.mass_scale));
    }
    let link_idx: HashMap<String, usize> = links.iter().enumerate().map(|(i, l)| (l.name.clone(), i)).collect();
    let collisions = collisions(&robot)?;
    let (mut joints, parent_joint) = joints(&robot, &link_idx)?;
    let ankle = ankle(&mut joints, options)?;
    let joint_idx: HashMap<String, usize> = joints.iter().enumerate().map(|(i, j)| (j.name.clone(), i)).collect();
    let (root, topo_joints) = tree_order(&links, &joints, &parent_joint)?;
    let closure = loop_closure(robot_el, &link_idx)?;
    let actuator = actuator(robot_el, &joints, &joint_idx)?;
    let knee = *joint_idx.get(knee_joint).ok_or_else(|| LegError::UnknownJoint {
        element: "knee joint parameter".into(),
        joint: knee_joint.to_string(),
    })?;
    expect_kind(&joints[knee], "knee", JointKind::is_hinge, "revolute or continuous")?;
    check_planar(&joints)?;
    let rod = actuator.joint;
    let barrel = check_topology(&links, &joints, &parent_joint, [knee, rod, ankle.unwrap_or(knee)], &actuator.name)?;
    let mut model = LegSpec {
        robot_name: robot.name.clone(),
        links,
        joints,
        root,
        topo_joints,
        parent_joint,
        knee,
        barrel,
        rod,
        closure,
        actuator,
        geo: LoopGeometry::default(),
        ankle,
        collisions,
    };
    check_moving_bodies(&model)?;
    model.geo = loop_geometry(&model)?;
    check_reachable(&model)?;
    Ok(model)
}

/// Refuse XML nested deeper than [`MAX_XML_DEPTH`] (in document order, without recursion).
fn check_nesting(doc: &roxmltree::Document) -> Result<(), LegError> {
    let mut depth: Vec<u32> = Vec::new();
    for n in doc.descendants() {
        let id = n.id().get_usize();
        let d = n.parent().map_or(0, |p| depth.get(p.id().get_usize()).copied().unwrap_or(0) + 1);
        if depth.len() <= id {
            depth.resize(id + 1, 0);
        }
        depth[id] = d;
        if d as usize > MAX_XML_DEPTH {
            let pos = doc.text_pos_at(n.range().start);
            return Err(LegError::Xml(format!(
                "elements nested more than {MAX_XML_DEPTH} deep (at <{}>, line {}, column {})",
                n.tag_name().name(),
                pos.row,
                pos.col
            )));
        }
    }
    Ok(())
}

/// A value must be finite and within `max` in magnitude.
fn sane(element: &str, what: &str, v: f64, max: f64) -> Result<f64, LegError> {
    if !v.is_finite() {
        return Err(LegError::Invalid {
            element: element.into(),
            message: format!("{what} is {v}, not a finite number"),
        });
    }
    if v.abs() > max {
        return Err(LegError::Invalid { element: element.into(), message: format!("{what} = {v} exceeds {max:e}") });
    }
    Ok(v)
}

fn sane3(element: &str, what: &str, v: [f64; 3], max: f64) -> Result<[f64; 3], LegError> {
    for (x, axis) in v.iter().zip(["x", "y", "z"]) {
        sane(element, &format!("{what} {axis}"), *x, max)?;
    }
    Ok(v)
}

/// Inertia tensor rotated into the link frame: `R I R^T` with R from the inertial's rpy.
fn rotated_inertia(rpy: [f64; 3], i: [[f64; 3]; 3]) -> [[f64; 3]; 3] {
    let r = DMat3::from_quat(DQuat::from_euler(EulerRot::ZYX, rpy[2], rpy[1], rpy[0]));
    (r * DMat3::from_cols_array_2d(&i) * r.transpose()).to_cols_array_2d()
}

/// Smallest eigenvalue of a symmetric 3x3 matrix, and all three.
fn eigenvalues(i: &[[f64; 3]; 3]) -> [f64; 3] {
    DSymmetricEigen3::eigenvalues(DMat3::from_cols_array_2d(i)).to_array()
}

/// Links with their mass properties (mass >= 0, inertia positive semi-definite, all finite).
fn links(robot: &urdf_rs::Robot) -> Result<Vec<LinkSpec>, LegError> {
    let mut out: Vec<LinkSpec> = Vec::with_capacity(robot.links.len());
    for l in &robot.links {
        if out.iter().any(|o| o.name == l.name) {
            return Err(LegError::NotATree(format!("link '{}' defined twice", l.name)));
        }
        let el = format!("link '{}' <inertial>", l.name);
        let m = sane(&el, "mass", l.inertial.mass.value, MAX_MASS_KG)?;
        if m < 0.0 {
            return Err(LegError::NonPositiveMass { link: l.name.clone(), mass: m });
        }
        let i = &l.inertial.inertia;
        for (v, n) in [(i.ixx, "ixx"), (i.ixy, "ixy"), (i.ixz, "ixz"), (i.iyy, "iyy"), (i.iyz, "iyz"), (i.izz, "izz")] {
            sane(&el, n, v, MAX_INERTIA_KG_M2)?;
        }
        let it = [[i.ixx, i.ixy, i.ixz], [i.ixy, i.iyy, i.iyz], [i.ixz, i.iyz, i.izz]];
        let ev = eigenvalues(&it);
        let scale = ev.iter().fold(0.0f64, |a, e| a.max(e.abs()));
        if ev.iter().any(|e| *e < -1e-12 * scale.max(1e-300)) {
            return Err(LegError::InertiaNotPositiveDefinite { link: l.name.clone(), eigenvalues: ev });
        }
        let com = sane3(&el, "origin xyz", l.inertial.origin.xyz.0, MAX_LENGTH_M)?;
        let rpy = sane3(&el, "origin rpy", l.inertial.origin.rpy.0, MAX_LIMIT)?;
        out.push(LinkSpec { name: l.name.clone(), mass_kg: m, com_m: com, inertia_kg_m2: rotated_inertia(rpy, it) });
    }
    Ok(out)
}

/// One URDF joint, checked: known links, finite origin, non-zero axis, ordered limits.
fn joint(j: &urdf_rs::Joint, link_idx: &HashMap<String, usize>) -> Result<JointSpec, LegError> {
    let kind = match j.joint_type {
        urdf_rs::JointType::Revolute => JointKind::Revolute,
        urdf_rs::JointType::Continuous => JointKind::Continuous,
        urdf_rs::JointType::Prismatic => JointKind::Prismatic,
        urdf_rs::JointType::Fixed => JointKind::Fixed,
        ref other => return Err(LegError::Unsupported(format!("joint '{}' has unsupported type {other:?}", j.name))),
    };
    let lookup = |n: &str, role: &str| {
        link_idx
            .get(n)
            .copied()
            .ok_or_else(|| LegError::UnknownLink { element: format!("joint '{}' {role}", j.name), link: n.to_string() })
    };
    let (parent, child) = (lookup(&j.parent.link, "parent")?, lookup(&j.child.link, "child")?);
    if parent == child {
        return Err(LegError::NotATree(format!("joint '{}' connects link '{}' to itself", j.name, j.parent.link)));
    }
    let el = format!("joint '{}'", j.name);
    let origin_xyz = sane3(&el, "origin xyz", j.origin.xyz.0, MAX_LENGTH_M)?;
    let origin_rpy = sane3(&el, "origin rpy", j.origin.rpy.0, MAX_LIMIT)?;
    let a = sane3(&el, "axis", j.axis.xyz.0, MAX_LIMIT)?;
    let n = (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt();
    if kind != JointKind::Fixed && n <= 1e-12 {
        return Err(LegError::Urdf(format!("joint '{}' has a zero axis", j.name)));
    }
    let axis = if n > 1e-12 { [a[0] / n, a[1] / n, a[2] / n] } else { [1.0, 0.0, 0.0] };
    let (lower, upper) =
        (sane(&el, "limit lower", j.limit.lower, MAX_LIMIT)?, sane(&el, "limit upper", j.limit.upper, MAX_LIMIT)?);
    if lower > upper && matches!(kind, JointKind::Revolute | JointKind::Prismatic) {
        return Err(LegError::Invalid { element: el, message: format!("limit lower {lower} is above upper {upper}") });
    }
    let limits =
        (matches!(kind, JointKind::Revolute | JointKind::Prismatic) && upper > lower).then_some((lower, upper));
    let damping = match &j.dynamics {
        Some(d) => sane(&el, "dynamics damping", d.damping, 1e6)?,
        None => 0.0,
    };
    if damping < 0.0 {
        return Err(LegError::Invalid { element: el, message: format!("dynamics damping {damping} is negative") });
    }
    Ok(JointSpec { name: j.name.clone(), kind, parent, child, origin_xyz, origin_rpy, axis, limits, damping })
}

/// All joints, and the joint whose child each link is.
fn joints(
    robot: &urdf_rs::Robot,
    link_idx: &HashMap<String, usize>,
) -> Result<(Vec<JointSpec>, Vec<Option<usize>>), LegError> {
    let mut joints: Vec<JointSpec> = Vec::with_capacity(robot.joints.len());
    let mut parent_joint: Vec<Option<usize>> = vec![None; link_idx.len()];
    for j in &robot.joints {
        if joints.iter().any(|o| o.name == j.name) {
            return Err(LegError::NotATree(format!("joint '{}' defined twice", j.name)));
        }
        let spec = joint(j, link_idx)?;
        if let Some(prev) = parent_joint[spec.child] {
            return Err(LegError::NotATree(format!(
                "link '{}' is the child of two joints ('{}' and '{}'), which closes a kinematic loop; use <loop_closure>",
                j.child.link, joints[prev].name, j.name
            )));
        }
        parent_joint[spec.child] = Some(joints.len());
        joints.push(spec);
    }
    Ok((joints, parent_joint))
}

/// The single root and the joints in parent-before-child order.
fn tree_order(
    links: &[LinkSpec],
    joints: &[JointSpec],
    parent_joint: &[Option<usize>],
) -> Result<(usize, Vec<usize>), LegError> {
    let roots: Vec<usize> = (0..links.len()).filter(|&l| parent_joint[l].is_none()).collect();
    let root = match roots.as_slice() {
        [] => return Err(LegError::NotATree("no root link (every link has a parent: cycle)".into())),
        [r] => *r,
        _ => {
            let names: Vec<&str> = roots.iter().map(|&r| links[r].name.as_str()).collect();
            return Err(LegError::NotATree(format!("several root links: {}", names.join(", "))));
        }
    };
    let mut children: Vec<Vec<usize>> = vec![Vec::new(); links.len()];
    for (ji, j) in joints.iter().enumerate() {
        children[j.parent].push(ji);
    }
    let mut topo = Vec::with_capacity(joints.len());
    let mut stack = vec![root];
    let mut seen = vec![false; links.len()];
    seen[root] = true;
    while let Some(l) = stack.pop() {
        for &ji in &children[l] {
            topo.push(ji);
            seen[joints[ji].child] = true;
            stack.push(joints[ji].child);
        }
    }
    if let Some(l) = (0..links.len()).find(|&l| !seen[l]) {
        return Err(LegError::NotATree(format!(
            "link '{}' is not reachable from root '{}' (kinematic cycle)",
            links[l].name, links[root].name
        )));
    }
    Ok((root, topo))
}

/// The one child element `<tag>` of `<robot>`.
fn find_one<'a>(robot_el: roxmltree::Node<'a, 'a>, tag: &str) -> Result<roxmltree::Node<'a, 'a>, LegError> {
    let mut it = robot_el.children().filter(|n| n.is_element() && n.tag_name().name() == tag);
    let first = it.next().ok_or_else(|| LegError::Missing { what: format!("<{tag}> element") })?;
    if it.next().is_some() {
        return Err(LegError::Unsupported(format!("more than one <{tag}> element")));
    }
    Ok(first)
}

fn attr(n: &roxmltree::Node, a: &str, what: &str) -> Result<String, LegError> {
    n.attribute(a).map(str::to_string).ok_or_else(|| LegError::Missing { what: format!("attribute '{a}' of {what}") })
}

fn parse_vec3(text: &str, what: &str) -> Result<[f64; 3], LegError> {
    let v: Vec<f64> = text
        .split_whitespace()
        .map(|t| t.parse::<f64>())
        .collect::<Result<_, _>>()
        .map_err(|e| LegError::Urdf(format!("{what}: cannot parse '{text}': {e}")))?;
    match v.as_slice() {
        [x, y, z] => sane3(what, "xyz", [*x, *y, *z], MAX_LENGTH_M),
        _ => Err(LegError::Urdf(format!("{what}: expected 3 numbers, got '{text}'"))),
    }
}

/// `<loop_closure name><link1 name xyz/><link2 name xyz/></loop_closure>`.
fn loop_closure(robot_el: roxmltree::Node, link_idx: &HashMap<String, usize>) -> Result<LoopClosureSpec, LegError> {
    let lc = find_one(robot_el, "loop_closure")?;
    let name = attr(&lc, "name", "<loop_closure>")?;
    let mut ends = Vec::new();
    for tag in ["link1", "link2"] {
        let what = format!("loop_closure '{name}' {tag}");
        let el = lc
            .children()
            .find(|n| n.is_element() && n.tag_name().name() == tag)
            .ok_or_else(|| LegError::Missing { what: format!("<{tag}> of loop_closure '{name}'") })?;
        let lname = attr(&el, "name", &what)?;
        let li = *link_idx
            .get(&lname)
            .ok_or_else(|| LegError::UnknownLink { element: what.clone(), link: lname.clone() })?;
        let xyz = match el.attribute("xyz") {
            Some(t) => parse_vec3(t, &what)?,
            None => [0.0; 3],
        };
        ends.push((li, xyz));
    }
    Ok(LoopClosureSpec { name, link1: ends[0].0, anchor1_m: ends[0].1, link2: ends[1].0, anchor2_m: ends[1].1 })
}

fn expect_kind(j: &JointSpec, role: &str, ok: fn(JointKind) -> bool, expected: &str) -> Result<(), LegError> {
    if ok(j.kind) {
        Ok(())
    } else {
        Err(LegError::WrongJointType {
            joint: j.name.clone(),
            role: role.into(),
            expected: expected.into(),
            found: j.kind.name().into(),
        })
    }
}

/// `<hydraulic_actuator name joint/>` on a prismatic joint.
fn actuator(
    robot_el: roxmltree::Node,
    joints: &[JointSpec],
    joint_idx: &HashMap<String, usize>,
) -> Result<ActuatorSpec, LegError> {
    let ha = find_one(robot_el, "hydraulic_actuator")?;
    let name = attr(&ha, "name", "<hydraulic_actuator>")?;
    let jname = attr(&ha, "joint", &format!("hydraulic_actuator '{name}'"))?;
    let rod = *joint_idx.get(&jname).ok_or_else(|| LegError::UnknownJoint {
        element: format!("hydraulic_actuator '{name}'"),
        joint: jname.clone(),
    })?;
    expect_kind(
        &joints[rod],
        &format!("joint of hydraulic_actuator '{name}'"),
        |k| k == JointKind::Prismatic,
        "prismatic",
    )?;
    Ok(ActuatorSpec { name, joint: rod })
}

/// The ankle joint's default name (`leg.ankle_joint`).
pub const DEFAULT_ANKLE_JOINT: &str = "ankle";

/// The ankle: locked (a fixed joint for everything downstream) unless `ankle_free`; a free
/// ankle must be a hinge from the knee's child (the shank, or a link welded to it) to the foot.
/// A URDF without a joint of the default name has no ankle (the foot welded to the shank).
fn ankle(joints: &mut [JointSpec], o: &LegOptions) -> Result<Option<usize>, LegError> {
    let found = joints.iter().position(|j| j.name == o.ankle_joint);
    match (found, o.ankle_free) {
        (Some(a), false) => {
            if joints[a].kind.is_hinge() {
                joints[a].kind = JointKind::Fixed;
            }
            Ok(None)
        }
        (None, false) => Ok(None),
        // No ankle: the foot is welded to the shank and stands on the ground as it is. A name
        // the user gave that is not in the URDF is a mistake.
        (None, true) if o.ankle_joint == DEFAULT_ANKLE_JOINT => Ok(None),
        (None, true) => Err(LegError::UnknownJoint { element: "leg.ankle_joint".into(), joint: o.ankle_joint.clone() }),
        (Some(a), true) => {
            expect_kind(&joints[a], "ankle (leg.ankle = \"free\")", JointKind::is_hinge, "revolute or continuous")?;
            Ok(Some(a))
        }
    }
}

/// Every `<collision>` of every link, sizes checked (> 0, finite, sane).
fn collisions(robot: &urdf_rs::Robot) -> Result<Vec<CollisionSpec>, LegError> {
    let mut out = Vec::new();
    for (li, l) in robot.links.iter().enumerate() {
        for (ci, c) in l.collision.iter().enumerate() {
            let el = format!("link '{}' <collision> {}", l.name, c.name.clone().unwrap_or_else(|| ci.to_string()));
            let size = |what: &str, v: f64| -> Result<f64, LegError> {
                let v = sane(&el, what, v, MAX_LENGTH_M)?;
                if v <= 0.0 {
                    return Err(LegError::Invalid {
                        element: el.clone(),
                        message: format!("{what} must be > 0, got {v}"),
                    });
                }
                Ok(v)
            };
            let shape = match &c.geometry {
                urdf_rs::Geometry::Box { size: s } => CollisionShape::Box {
                    size: [size("box x", s.0[0])?, size("box y", s.0[1])?, size("box z", s.0[2])?],
                },
                urdf_rs::Geometry::Cylinder { radius, length } => {
                    CollisionShape::Cylinder { radius: size("radius", *radius)?, length: size("length", *length)? }
                }
                urdf_rs::Geometry::Capsule { radius, length } => {
                    CollisionShape::Capsule { radius: size("radius", *radius)?, length: size("length", *length)? }
                }
                urdf_rs::Geometry::Sphere { radius } => CollisionShape::Sphere { radius: size("radius", *radius)? },
                urdf_rs::Geometry::Mesh { filename, .. } => CollisionShape::Mesh { filename: filename.clone() },
            };
            out.push(CollisionSpec {
                link: li,
                origin_xyz: sane3(&el, "origin xyz", c.origin.xyz.0, MAX_LENGTH_M)?,
                origin_rpy: sane3(&el, "origin rpy", c.origin.rpy.0, MAX_LIMIT)?,
                shape,
            });
        }
    }
    Ok(out)
}

/// The planar loop geometry, everything in the root (thigh) frame.
fn loop_geometry(m: &LegSpec) -> Result<LoopGeometry, LegError> {
    let joints = &m.joints;
    // (ancestor, planar pose of the link in it, y offset): the fixed-joint walk, planar.
    let rigid_anchor = |l: usize| -> (usize, Pose2, f64) {
        let (anc, chain) = m.fixed_chain(l);
        let pose = chain.iter().fold(Pose2::IDENTITY, |pose, &ji| joint_origin(&joints[ji]).mul(&pose));
        (anc, pose, chain.iter().map(|&ji| joints[ji].origin_xyz[1]).sum())
    };
    let (knee, barrel, rod) = (m.knee, m.barrel, m.rod);
    let (kb, fk, yk) = rigid_anchor(joints[knee].parent);
    let (bb, fb, yb) = rigid_anchor(joints[barrel].parent);
    if kb != m.root || bb != m.root {
        return Err(LegError::Unsupported(format!(
            "knee '{}' and barrel pivot '{}' must both be attached (directly or via fixed joints) to the root link '{}'",
            joints[knee].name, joints[barrel].name, m.links[m.root].name
        )));
    }
    let (shank, rod_link, c) = (joints[knee].child, joints[rod].child, &m.closure);
    let (a1, a2) = (rigid_anchor(c.link1), rigid_anchor(c.link2));
    let (p1, p2) = (P2::new(c.anchor1_m[0], c.anchor1_m[2]), P2::new(c.anchor2_m[0], c.anchor2_m[2]));
    let (rod_side, rod_p, rod_y, shank_side, shank_p, shank_y) = if a1.0 == rod_link && a2.0 == shank {
        (a1, p1, c.anchor1_m[1], a2, p2, c.anchor2_m[1])
    } else if a2.0 == rod_link && a1.0 == shank {
        (a2, p2, c.anchor2_m[1], a1, p1, c.anchor1_m[1])
    } else {
        return Err(LegError::Unsupported(format!(
            "loop_closure '{}' must join the actuator rod '{}' and the knee child '{}' (or links welded to them)",
            c.name, m.links[rod_link].name, m.links[shank].name
        )));
    };
    let (rod_point, shank_point) = (rod_side.1.apply(rod_p), shank_side.1.apply(shank_p));
    let (ko, bo, ro) = (joint_origin(&joints[knee]), joint_origin(&joints[barrel]), joint_origin(&joints[rod]));
    let ra = joints[rod].axis;
    let y_rod = yb + joints[barrel].origin_xyz[1] + joints[rod].origin_xyz[1] + rod_side.2 + rod_y;
    let y_shank = yk + joints[knee].origin_xyz[1] + shank_side.2 + shank_y;
    if (y_rod - y_shank).abs() > 1e-9 {
        return Err(LegError::Unsupported(format!(
            "loop_closure '{}' anchors lie at different y ({y_rod} vs {y_shank} m)",
            c.name
        )));
    }
    let (knee_origin, barrel_origin) = (fk.mul(&ko), fb.mul(&bo));
    Ok(LoopGeometry {
        triangle: super::model::KneeTriangle::new(&knee_origin, shank_point, &barrel_origin),
        knee_origin,
        knee_sign: joints[knee].axis[1].signum(),
        shank_point,
        barrel_origin,
        barrel_sign: joints[barrel].axis[1].signum(),
        u: ro.apply(rod_point),
        v: P2::new(ra[0], ra[2]).rot(ro.a),
        rod_limits: joints[rod].limits.unwrap_or((f64::NEG_INFINITY, f64::INFINITY)),
        knee_range: joints[knee].limits.unwrap_or(DEFAULT_KNEE_RANGE_RAD),
        rod_point,
    })
}

/// The rod reaches the shank mounting point, within its stroke, over the whole knee range.
fn check_reachable(m: &LegSpec) -> Result<(), LegError> {
    let (lo, hi) = m.geo.knee_range;
    let n = 200;
    for k in 0..=n {
        m.loop_solution_checked(lo + (hi - lo) * k as f64 / n as f64)?;
    }
    Ok(())
}

/// The URDF constructors of the leg model.
impl LegSpec {
    /// Load and validate a URDF file. `knee_joint` names the knee hinge (usually `"knee"`).
    pub fn from_urdf_file(path: impl AsRef<Path>, knee_joint: &str) -> Result<Self, LegError> {
        let path = path.as_ref();
        let text = std::fs::read_to_string(path).map_err(|source| LegError::Io { path: path.to_path_buf(), source })?;
        Self::from_urdf_str(&text, knee_joint)
    }

    /// Parse and validate URDF text. `knee_joint` names the knee hinge (usually `"knee"`);
    /// the ankle (if any) is locked. See this module for what is checked.
    pub fn from_urdf_str(text: &str, knee_joint: &str) -> Result<Self, LegError> {
        parse(text, &LegOptions { knee_joint: knee_joint.into(), ..Default::default() })
    }

    /// Parse and validate URDF text with explicit options.
    pub fn from_urdf_with(text: &str, options: &LegOptions) -> Result<Self, LegError> {
        parse(text, options)
    }
}
