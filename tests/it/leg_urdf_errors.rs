//! Test 4: bad URDF inputs give the right error variant.
use crate::common::leg_reference::manifest;
use exoleg::leg::*;

fn good() -> String {
    std::fs::read_to_string(manifest("urdf/exo_leg.urdf")).unwrap()
}

fn load(text: &str) -> Result<LegModel, LegError> {
    LegModel::from_urdf_str(text, "knee")
}

fn replaced(from: &str, to: &str) -> String {
    let g = good();
    assert!(g.contains(from), "test fixture does not contain {from:?}");
    g.replacen(from, to, 1)
}

#[test]
fn good_file_loads() {
    let m = LegModel::from_urdf_file(manifest("urdf/exo_leg.urdf"), "knee").unwrap();
    assert_eq!(m.links().len(), 5);
    assert_eq!(m.actuator().name, "knee_cylinder");
    assert_eq!(m.loop_closure().name, "rod_end");
    assert_eq!(m.rod_end_in_shank_m(), (-0.05, -0.10));
}

#[test]
fn missing_file() {
    let e = LegModel::from_urdf_file("/nonexistent/leg.urdf", "knee").unwrap_err();
    assert!(matches!(e, LegError::Io { .. }), "{e}");
    println!("{e}");
}

#[test]
fn malformed_xml() {
    let g = good();
    let e = load(&g[..g.len() / 2]).unwrap_err();
    assert!(matches!(e, LegError::Xml(_)), "{e}");
    let e = load(&g.replacen("</link>", "</lnk>", 1)).unwrap_err();
    assert!(matches!(e, LegError::Xml(_)), "{e}");
    println!("{e}");
}

#[test]
fn closure_unknown_link() {
    let e = load(&replaced(r#"<link2 name="shank""#, r#"<link2 name="shin""#)).unwrap_err();
    assert!(matches!(&e, LegError::UnknownLink { link, .. } if link == "shin"), "{e}");
    assert!(e.to_string().contains("rod_end"), "{e}");
    println!("{e}");
}

#[test]
fn joint_unknown_link() {
    let e = load(&replaced(r#"<child link="foot"/>"#, r#"<child link="toe"/>"#)).unwrap_err();
    assert!(matches!(&e, LegError::UnknownLink { link, .. } if link == "toe"), "{e}");
    println!("{e}");
}

#[test]
fn actuator_unknown_joint() {
    let e = load(&replaced(r#"joint="rod_slide""#, r#"joint="rod_slid""#)).unwrap_err();
    assert!(matches!(&e, LegError::UnknownJoint { joint, .. } if joint == "rod_slid"), "{e}");
    assert!(e.to_string().contains("knee_cylinder"), "{e}");
    println!("{e}");
}

#[test]
fn actuator_not_prismatic() {
    let e = load(&replaced(r#"joint="rod_slide""#, r#"joint="barrel_pivot""#)).unwrap_err();
    assert!(matches!(&e, LegError::WrongJointType { joint, .. } if joint == "barrel_pivot"), "{e}");
    println!("{e}");
}

#[test]
fn unknown_knee_parameter() {
    let e = LegModel::from_urdf_str(&good(), "left_knee").unwrap_err();
    assert!(matches!(&e, LegError::UnknownJoint { joint, .. } if joint == "left_knee"), "{e}");
    let e = LegModel::from_urdf_str(&good(), "rod_slide").unwrap_err();
    assert!(matches!(&e, LegError::WrongJointType { .. }), "{e}");
}

#[test]
fn zero_and_negative_mass() {
    for m in ["0", "-0.6"] {
        let e = load(&replaced(r#"<mass value="0.6"/>"#, &format!(r#"<mass value="{m}"/>"#))).unwrap_err();
        assert!(matches!(&e, LegError::NonPositiveMass { link, .. } if link == "barrel"), "{e}");
        println!("{e}");
    }
}

#[test]
fn inertia_not_positive_definite() {
    // Negative diagonal.
    let e = load(&replaced(r#"iyy="0.0401872""#, r#"iyy="-0.0401872""#)).unwrap_err();
    assert!(matches!(&e, LegError::InertiaNotPositiveDefinite { link, .. } if link == "shank"), "{e}");
    // Positive diagonal but indefinite (huge product of inertia).
    let e =
        load(&replaced(r#"<inertia ixx="0.0383183" ixy="0""#, r#"<inertia ixx="0.0383183" ixy="0.5""#)).unwrap_err();
    assert!(matches!(&e, LegError::InertiaNotPositiveDefinite { link, .. } if link == "shank"), "{e}");
    println!("{e}");
}

#[test]
fn two_roots() {
    let e = load(&replaced("<link name=\"rod\">", "<link name=\"orphan\">\n    <inertial><mass value=\"1\"/><inertia ixx=\"1\" ixy=\"0\" ixz=\"0\" iyy=\"1\" iyz=\"0\" izz=\"1\"/></inertial>\n  </link>\n  <link name=\"rod\">")).unwrap_err();
    assert!(matches!(&e, LegError::NotATree(msg) if msg.contains("orphan")), "{e}");
    println!("{e}");
}

#[test]
fn kinematic_cycle() {
    // A joint making the thigh a child of the foot: no root left.
    let cyc = r#"<joint name="loop" type="fixed"><parent link="foot"/><child link="thigh"/></joint>
  <loop_closure"#;
    let e = load(&replaced("<loop_closure", cyc)).unwrap_err();
    assert!(matches!(e, LegError::NotATree(_)), "{e}");
    println!("{e}");
    // A link with two parent joints (closing a loop inside URDF).
    let dbl = r#"<joint name="extra" type="fixed"><parent link="thigh"/><child link="rod"/></joint>
  <loop_closure"#;
    let e = load(&replaced("<loop_closure", dbl)).unwrap_err();
    assert!(matches!(&e, LegError::NotATree(msg) if msg.contains("rod")), "{e}");
    println!("{e}");
}

#[test]
fn missing_extension_elements() {
    let g = good();
    let start = g.find("<loop_closure").unwrap();
    let end = g.find("</loop_closure>").unwrap() + "</loop_closure>".len();
    let no_closure = format!("{}{}", &g[..start], &g[end..]);
    let e = load(&no_closure).unwrap_err();
    assert!(matches!(&e, LegError::Missing { what } if what.contains("loop_closure")), "{e}");
    let e = load(&replaced(r#"<hydraulic_actuator name="knee_cylinder" joint="rod_slide"/>"#, "")).unwrap_err();
    assert!(matches!(&e, LegError::Missing { what } if what.contains("hydraulic_actuator")), "{e}");
}

#[test]
fn mounting_point_out_of_stroke() {
    // Rod end 0.3 m below the knee: the cylinder would need more than the 0.2 m stroke.
    let e = load(&replaced(r#"xyz="-0.05 0 -0.1"/>"#, r#"xyz="-0.05 0 -0.3"/>"#)).unwrap_err();
    assert!(matches!(&e, LegError::Unreachable { actuator, .. } if actuator == "knee_cylinder"), "{e}");
    println!("{e}");
    // Stroke too short for the knee range.
    let e = load(&replaced(r#"lower="0" upper="0.2""#, r#"lower="0.05" upper="0.1""#)).unwrap_err();
    assert!(matches!(e, LegError::Unreachable { .. }), "{e}");
    println!("{e}");
}

#[test]
fn no_solution_at_initial_angle() {
    let m = LegModel::from_urdf_file(manifest("urdf/exo_leg.urdf"), "knee").unwrap();
    // 150 deg flexion would need a negative rod extension (below the stroke).
    let e = Leg::new(&m, 150f64.to_radians(), 1e-3).err().unwrap();
    assert!(matches!(e, LegError::Unreachable { .. }), "{e}");
    let e = Leg::new(&m, 0.3, 0.0).err().unwrap();
    assert!(matches!(e, LegError::InvalidArgument(_)), "{e}");
    println!("{e}");
}

#[test]
fn non_planar_axis_rejected() {
    let e = load(&replaced(r#"<axis xyz="0 1 0"/>"#, r#"<axis xyz="1 0 0"/>"#)).unwrap_err();
    assert!(matches!(e, LegError::Unsupported(_)), "{e}");
}
