//! Test 4: bad URDF inputs give the right error variant.
use crate::common::leg_reference::manifest;
use exoleg::leg::*;

fn good() -> String {
    std::fs::read_to_string(manifest("urdf/exo_leg.urdf")).unwrap()
}

fn load(text: &str) -> Result<LegSpec, LegError> {
    LegSpec::from_urdf_str(text, "knee")
}

fn replaced(from: &str, to: &str) -> String {
    let g = good();
    assert!(g.contains(from), "test fixture does not contain {from:?}");
    g.replacen(from, to, 1)
}

#[test]
fn good_file_loads() {
    let m = LegSpec::from_urdf_file(manifest("urdf/exo_leg.urdf"), "knee").unwrap();
    assert_eq!(m.links().len(), 5);
    assert_eq!(m.actuator().name, "knee_cylinder");
    assert_eq!(m.loop_closure().name, "rod_end");
    assert_eq!(m.rod_end_in_shank_m(), (-0.05, -0.10));
}

#[test]
fn missing_file() {
    let e = LegSpec::from_urdf_file("/nonexistent/leg.urdf", "knee").unwrap_err();
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
    let e = LegSpec::from_urdf_str(&good(), "left_knee").unwrap_err();
    assert!(matches!(&e, LegError::UnknownJoint { joint, .. } if joint == "left_knee"), "{e}");
    let e = LegSpec::from_urdf_str(&good(), "rod_slide").unwrap_err();
    assert!(matches!(&e, LegError::WrongJointType { .. }), "{e}");
}

#[test]
fn negative_mass_and_a_moving_body_without_mass() {
    let e = load(&replaced(r#"<mass value="0.6"/>"#, r#"<mass value="-0.6"/>"#)).unwrap_err();
    assert!(matches!(&e, LegError::NonPositiveMass { link, .. } if link == "barrel"), "{e}");
    // Mass 0 is legal for a link, but the barrel moves on its own hinge: its body needs mass.
    let e = load(&replaced(r#"<mass value="0.6"/>"#, r#"<mass value="0"/>"#)).unwrap_err();
    assert!(matches!(&e, LegError::MovingBodyWithoutMass { link, .. } if link == "barrel"), "{e}");
    assert!(e.to_string().contains("barrel") && e.to_string().contains("no mass"), "{e}");
    // A point mass (zero inertia tensor) on a moving joint has no rotational inertia.
    let point = replaced(
        r#"<inertia ixx="0.00303375" ixy="0" ixz="0" iyy="0.00303375" iyz="0" izz="0.0003075"/>"#,
        r#"<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/>"#,
    );
    let e = load(&point).unwrap_err();
    assert!(matches!(&e, LegError::MovingBodyWithoutInertia { link, .. } if link == "barrel"), "{e}");
}

/// Legal URDF the loader used to refuse (issue 10): a link with no `<inertial>` (mass 0 by the
/// spec), a massless frame link and a point mass on fixed joints. They merge into the shank's
/// body, so the leg's dynamics are those of the merged masses.
#[test]
fn frames_without_inertial_and_point_masses_on_fixed_joints_are_merged() {
    let extra = r#"<link name="imu_frame"/>
  <link name="strap_mass"><inertial><origin xyz="0.02 0 -0.1"/><mass value="0.5"/><inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial></link>
  <joint name="imu" type="fixed"><parent link="shank"/><child link="imu_frame"/><origin xyz="0 0 -0.3"/></joint>
  <joint name="strap" type="fixed"><parent link="imu_frame"/><child link="strap_mass"/><origin xyz="0 0 0"/></joint>
  <loop_closure"#;
    let m = load(&replaced("<loop_closure", extra)).expect("legal URDF");
    assert_eq!(m.links().len(), 7);
    // The point mass adds 0.5 kg at 0.4 m below the knee: the generalized inertia grows by
    // m r^2 at full extension (r = |(0.02, -0.4)| in the shank frame).
    let base = load(&good()).unwrap();
    let (m0, m1) = (generalized_inertia_at(&base, 0.0).unwrap(), generalized_inertia_at(&m, 0.0).unwrap());
    let expected = 0.5 * (0.02f64 * 0.02 + 0.4 * 0.4);
    assert!((m1 - m0 - expected).abs() < 1e-7, "inertia grew by {} vs {expected}", m1 - m0);
    // And Rapier builds and steps it.
    let mut leg = Leg::new(&m, 0.5, 1e-3).unwrap();
    leg.step(0.0, None);
    assert!(leg.knee_angle_rad().is_finite());
}

/// Non-finite, absurd, reversed or NaN values are refused, naming the element.
#[test]
fn non_finite_absurd_and_reversed_values_name_the_element() {
    let cases: [(&str, &str, &[&str]); 7] = [
        (r#"<mass value="3.2475"/>"#, r#"<mass value="nan"/>"#, &["shank", "mass", "finite"]),
        (r#"<mass value="3.2475"/>"#, r#"<mass value="1e9"/>"#, &["shank", "mass", "exceeds"]),
        (r#"iyy="0.0401872""#, r#"iyy="inf""#, &["shank", "iyy"]),
        (
            r#"<origin xyz="0 0 -0.424383" rpy="0 0 0"/>"#,
            r#"<origin xyz="0 0 NaN" rpy="0 0 0"/>"#,
            &["knee", "origin xyz z"],
        ),
        (
            r#"<origin xyz="0 0 -0.424383" rpy="0 0 0"/>"#,
            r#"<origin xyz="0 0 -4e5" rpy="0 0 0"/>"#,
            &["knee", "exceeds"],
        ),
        (
            r#"lower="-0.174533" upper="1.74533""#,
            r#"lower="1.74533" upper="-0.174533""#,
            &["knee", "lower", "above upper"],
        ),
        (r#"lower="-0.174533" upper="1.74533""#, r#"lower="nan" upper="1.74533""#, &["knee", "limit lower"]),
    ];
    for (from, to, needles) in cases {
        let e = load(&replaced(from, to)).unwrap_err().to_string();
        for n in needles {
            assert!(e.contains(n), "{to}: {n:?} not in {e:?}");
        }
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
    let m = LegSpec::from_urdf_file(manifest("urdf/exo_leg.urdf"), "knee").unwrap();
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
