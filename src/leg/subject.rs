//! The built-in leg scaled to a subject (`[subject]`): the port of `urdf/gen_urdf.py`, which
//! generated the two built-in URDFs, with the template exoskeleton of the subject's sex.
//!
//! - Segment lengths are de Leva's (1996, Table 4) fractions of the stature; with a leg length
//!   the thigh, the shank and the ankle height are scaled together so the hip-joint-centre to
//!   floor distance (thigh + shank + 0.039 stature) is that length.
//! - Segment masses are de Leva's fractions of the body mass, the centres of mass and radii of
//!   gyration his fractions of the segment length (sagittal radius about y).
//! - The exoskeleton is the template of the subject's sex (`exo_leg` for men, `exo_leg_small`
//!   for women), its cylinder mounts, closed length, stroke, barrel and rod lengths scaled by
//!   `k` = the subject's thigh length over the template's (thigh and shank scale alike, so
//!   this is exact): the cylinder's length is then `k` times the template's at every knee
//!   angle, so it spans the same knee range with the same margins in proportion. The barrel
//!   and rod keep their masses.
//! - The foot: heel and ball contact spheres as the templates have them (radius 20 mm, the
//!   ball at 75 % of the foot length), the ankle 0.039 x stature above the sole (Winter 2009).

use std::fmt::Write;

/// The subject's sex (selects de Leva's table and the exoskeleton template).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, Default)]
#[serde(rename_all = "snake_case")]
pub enum Sex {
    /// de Leva's male table, the `exo_leg` template (1.75 m).
    #[default]
    Male,
    /// de Leva's female table, the `exo_leg_small` template (1.60 m).
    Female,
}

/// A subject to scale the built-in leg to.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubjectBody {
    /// Body mass (kg).
    pub mass_kg: f64,
    /// Stature (m).
    pub height_m: f64,
    /// Hip joint centre to floor (m), if measured; else from the stature.
    pub leg_length_m: Option<f64>,
    /// Sex.
    pub sex: Sex,
}

/// de Leva (1996), Table 4, per segment: mass fraction, CoM from the proximal end and radii of
/// gyration (sagittal, transverse, longitudinal) as fractions of the length, length (mm) of
/// the reference subject; and the reference stature (mm). The rows of `gen_urdf.py`.
struct Table {
    stature_mm: f64,
    thigh: [f64; 6],
    shank: [f64; 6],
    foot: [f64; 6],
}

const MALE: Table = Table {
    stature_mm: 1741.0,
    thigh: [0.1416, 0.4095, 0.329, 0.329, 0.149, 422.2],
    shank: [0.0433, 0.4459, 0.255, 0.249, 0.103, 434.0],
    foot: [0.0137, 0.4415, 0.257, 0.245, 0.124, 258.1],
};

const FEMALE: Table = Table {
    stature_mm: 1735.0,
    thigh: [0.1478, 0.3612, 0.369, 0.364, 0.162, 368.5],
    shank: [0.0481, 0.4352, 0.267, 0.263, 0.092, 432.3],
    foot: [0.0129, 0.4014, 0.299, 0.279, 0.139, 228.3],
};

/// The exoskeleton of a built-in URDF, at its template subject's size.
struct Template {
    name: &'static str,
    height_m: f64,
    pivot: [f64; 2],
    rod_end: [f64; 2],
    /// Barrel: mass (kg), length (m), outer and inner radius (m).
    barrel: [f64; 4],
    /// Rod: mass (kg), length (m), radius (m).
    rod: [f64; 3],
    closed_len_m: f64,
    stroke_m: f64,
    barrel_axis: &'static str,
    heel_back_m: f64,
    foot_com_below_ankle_m: f64,
}

const EXO_LEG: Template = Template {
    name: "exo_leg",
    height_m: 1.75,
    pivot: [-0.06, -0.10],
    rod_end: [-0.05, -0.10],
    barrel: [0.6, 0.24, 0.025, 0.020],
    rod: [0.3, 0.22, 0.008],
    closed_len_m: 0.24,
    stroke_m: 0.20,
    barrel_axis: "0 1 0",
    heel_back_m: 0.05,
    foot_com_below_ankle_m: 0.04,
};

const EXO_LEG_SMALL: Template = Template {
    name: "exo_leg_small",
    height_m: 1.60,
    pivot: [-0.07, -0.08],
    rod_end: [-0.055, -0.09],
    barrel: [0.9, 0.22, 0.030, 0.024],
    rod: [0.45, 0.20, 0.010],
    closed_len_m: 0.185,
    stroke_m: 0.18,
    barrel_axis: "0 -1 0",
    heel_back_m: 0.045,
    foot_com_below_ankle_m: 0.035,
};

/// Radius of the heel and ball contact spheres (m).
const SOLE_RADIUS_M: f64 = 0.02;
/// Ankle height over stature (Winter 2009).
const ANKLE_HEIGHT_PER_STATURE: f64 = 0.039;

/// A segment's length (m), mass (kg), CoM from the proximal end (m) and inertias (kg m^2:
/// sagittal, transverse, longitudinal).
struct Segment {
    length_m: f64,
    mass_kg: f64,
    com_m: f64,
    i_sag: f64,
    i_tr: f64,
    i_long: f64,
}

fn segment(row: &[f64; 6], stature_scale: f64, length_scale: f64, mass_kg: f64) -> Segment {
    let [mf, cf, rs, rt, rl, lmm] = *row;
    let l = lmm / 1000.0 * stature_scale * length_scale;
    let m = mf * mass_kg;
    Segment {
        length_m: l,
        mass_kg: m,
        com_m: cf * l,
        i_sag: m * (rs * l).powi(2),
        i_tr: m * (rt * l).powi(2),
        i_long: m * (rl * l).powi(2),
    }
}

/// Transverse and axial inertia (kg m^2) of a tube about its centre.
fn tube(m: f64, length: f64, ro: f64, ri: f64) -> (f64, f64) {
    (m * (length * length / 12.0 + (ro * ro + ri * ri) / 4.0), m * (ro * ro + ri * ri) / 2.0)
}

fn inertial(out: &mut String, m: f64, com: [f64; 3], i: [f64; 3]) {
    let _ = write!(
        out,
        "    <inertial>\n      <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n      <mass value=\"{m}\"/>\n      \
         <inertia ixx=\"{}\" ixy=\"0\" ixz=\"0\" iyy=\"{}\" iyz=\"0\" izz=\"{}\"/>\n    </inertial>\n",
        com[0], com[1], com[2], i[0], i[1], i[2]
    );
}

fn sphere(out: &mut String, name: &str, x: f64, z: f64, r: f64) {
    let _ = write!(
        out,
        "    <collision name=\"{name}\">\n      <origin xyz=\"{x} 0 {z}\" rpy=\"0 0 0\"/>\n      \
         <geometry><sphere radius=\"{r}\"/></geometry>\n    </collision>\n"
    );
}

fn joint(out: &mut String, name_kind: [&str; 2], links: [&str; 2], xyz: [f64; 3], axis: &str, limit: [f64; 4]) {
    let ([name, kind], [parent, child]) = (name_kind, links);
    let _ = write!(
        out,
        "  <joint name=\"{name}\" type=\"{kind}\">\n    <parent link=\"{parent}\"/>\n    <child link=\"{child}\"/>\n    \
         <origin xyz=\"{} {} {}\" rpy=\"0 0 0\"/>\n    <axis xyz=\"{axis}\"/>\n    \
         <limit lower=\"{}\" upper=\"{}\" effort=\"{}\" velocity=\"{}\"/>\n  </joint>\n",
        xyz[0], xyz[1], xyz[2], limit[0], limit[1], limit[2], limit[3]
    );
}

/// The segments of `s` (thigh, shank, foot), the ankle height (m) and the exoskeleton's
/// scale `k` against the template.
fn body(s: &SubjectBody) -> ([Segment; 3], f64, f64, &'static Template) {
    let (table, template) = match s.sex {
        Sex::Male => (&MALE, &EXO_LEG),
        Sex::Female => (&FEMALE, &EXO_LEG_SMALL),
    };
    let st = s.height_m * 1000.0 / table.stature_mm;
    let ankle = ANKLE_HEIGHT_PER_STATURE * s.height_m;
    let natural = (table.thigh[5] + table.shank[5]) / 1000.0 * st + ankle;
    let leg_scale = s.leg_length_m.map_or(1.0, |l| l / natural);
    let thigh = segment(&table.thigh, st, leg_scale, s.mass_kg);
    let shank = segment(&table.shank, st, leg_scale, s.mass_kg);
    let foot = segment(&table.foot, st, 1.0, s.mass_kg);
    let template_thigh = table.thigh[5] / 1000.0 * template.height_m * 1000.0 / table.stature_mm;
    let k = thigh.length_m / template_thigh;
    ([thigh, shank, foot], ankle * leg_scale, k, template)
}

/// The hip-joint-centre-to-floor distance of `s` (m): the given leg length, else the thigh,
/// shank and ankle height de Leva's proportions give the stature.
pub fn leg_length_m(s: &SubjectBody) -> f64 {
    let ([thigh, shank, _], ankle, _, _) = body(s);
    thigh.length_m + shank.length_m + ankle
}

/// The built-in leg `[subject]` scales for `s` (`builtin:exo_leg` for a man,
/// `builtin:exo_leg_small` for a woman).
pub fn template_urdf(s: &SubjectBody) -> String {
    format!("builtin:{}", body(s).3.name)
}

/// How every URDF [`scaled_urdf`] writes begins.
const SCALED_URDF_HEAD: &str = "<?xml version=\"1.0\"?>\n<!-- exoleg: the built-in leg scaled to a ";

/// True when `f` is a URDF `exoleg urdf` wrote (it begins as [`scaled_urdf`]'s do, and is
/// small): the one file `exoleg urdf --out` replaces.
pub fn is_scaled_urdf(f: &mut std::fs::File, len: u64) -> bool {
    use std::io::Read;
    let mut head = vec![0u8; SCALED_URDF_HEAD.len()];
    len < 1 << 20 && f.read_exact(&mut head).is_ok() && head == SCALED_URDF_HEAD.as_bytes()
}

/// The URDF of the built-in leg scaled to `s` (see the module doc). `s` must be valid
/// (positive, finite; checked by the scenario).
pub fn scaled_urdf(s: &SubjectBody) -> String {
    let ([t, sh, ft], ankle_h, k, tp) = body(s);
    let sex = if s.sex == Sex::Male { "male" } else { "female" };
    let mut out = format!(
        "<?xml version=\"1.0\"?>\n<!-- exoleg: the built-in leg scaled to a {sex} subject of {} kg, {} m{}: de Leva 1996, \
         the {} exoskeleton scaled by {k:.4}; see src/leg/subject.rs -->\n<robot name=\"{}_subject\">\n",
        s.mass_kg,
        s.height_m,
        s.leg_length_m.map_or(String::new(), |l| format!(", leg length {l} m")),
        tp.name,
        tp.name
    );
    out += "  <link name=\"thigh\">\n";
    inertial(&mut out, t.mass_kg, [0.0, 0.0, -t.com_m], [t.i_tr, t.i_sag, t.i_long]);
    out += "  </link>\n  <link name=\"shank\">\n";
    inertial(&mut out, sh.mass_kg, [0.0, 0.0, -sh.com_m], [sh.i_tr, sh.i_sag, sh.i_long]);
    out += "  </link>\n  <link name=\"foot\">\n";
    let heel_back = tp.heel_back_m * k;
    let below = tp.foot_com_below_ankle_m * k;
    inertial(&mut out, ft.mass_kg, [ft.com_m - heel_back, 0.0, -below], [ft.i_long, ft.i_sag, ft.i_tr]);
    let r = SOLE_RADIUS_M;
    sphere(&mut out, "heel", -heel_back + r, -ankle_h + r, r);
    sphere(&mut out, "toe", -heel_back + 0.75 * ft.length_m, -ankle_h + r, r);
    let [bm, bl, bro, bri] = tp.barrel;
    let [rm, rl, rro] = tp.rod;
    let (bl, rl) = (bl * k, rl * k);
    let (b_it, b_ia) = tube(bm, bl, bro, bri);
    let (r_it, r_ia) = tube(rm, rl, rro, 0.0);
    out += "  </link>\n  <link name=\"barrel\">\n";
    inertial(&mut out, bm, [0.0, 0.0, -bl / 2.0], [b_it, b_it, b_ia]);
    out += "  </link>\n  <link name=\"rod\">\n";
    inertial(&mut out, rm, [0.0, 0.0, rl / 2.0], [r_it, r_it, r_ia]);
    out += "  </link>\n";
    let deg = f64::to_radians;
    joint(
        &mut out,
        ["knee", "revolute"],
        ["thigh", "shank"],
        [0.0, 0.0, -t.length_m],
        "0 1 0",
        [deg(-10.0), deg(100.0), 300.0, 10.0],
    );
    joint(
        &mut out,
        ["ankle", "revolute"],
        ["shank", "foot"],
        [0.0, 0.0, -sh.length_m],
        "0 -1 0",
        [deg(-40.0), deg(30.0), 200.0, 10.0],
    );
    let pivot = [tp.pivot[0] * k, 0.0, tp.pivot[1] * k];
    joint(&mut out, ["barrel_pivot", "revolute"], ["thigh", "barrel"], pivot, tp.barrel_axis, [-1.0, 1.0, 0.0, 10.0]);
    let closed = [0.0, 0.0, -tp.closed_len_m * k];
    joint(
        &mut out,
        ["rod_slide", "prismatic"],
        ["barrel", "rod"],
        closed,
        "0 0 -1",
        [0.0, tp.stroke_m * k, 5000.0, 1.0],
    );
    let _ = write!(
        out,
        "  <loop_closure name=\"rod_end\">\n    <link1 name=\"rod\" xyz=\"0 0 0\"/>\n    \
         <link2 name=\"shank\" xyz=\"{} 0 {}\"/>\n  </loop_closure>\n  \
         <hydraulic_actuator name=\"knee_cylinder\" joint=\"rod_slide\"/>\n</robot>\n",
        tp.rod_end[0] * k,
        tp.rod_end[1] * k
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::leg::{LegOptions, LegSpec, BUILTIN_URDFS};

    fn close(a: f64, b: f64) -> bool {
        (a - b).abs() <= 1e-5 * a.abs().max(b.abs()).max(1e-3)
    }

    /// The templates' own subjects give the built-in URDFs (printed there to 6 digits).
    #[test]
    fn template_subjects_give_the_builtin_legs() {
        let cases = [
            (SubjectBody { mass_kg: 75.0, height_m: 1.75, leg_length_m: None, sex: Sex::Male }, 0),
            (SubjectBody { mass_kg: 60.0, height_m: 1.60, leg_length_m: None, sex: Sex::Female }, 1),
        ];
        for (s, i) in cases {
            let ours = LegSpec::from_urdf_with(&scaled_urdf(&s), &LegOptions::default()).unwrap();
            let theirs = LegSpec::from_urdf_with(BUILTIN_URDFS[i].1, &LegOptions::default()).unwrap();
            for (a, b) in ours.links().iter().zip(theirs.links()) {
                assert!(close(a.mass_kg, b.mass_kg), "{}: {} vs {}", a.name, a.mass_kg, b.mass_kg);
                for j in 0..3 {
                    assert!(close(a.com_m[j], b.com_m[j]), "{} com", a.name);
                    assert!(close(a.inertia_kg_m2[j][j], b.inertia_kg_m2[j][j]), "{} inertia", a.name);
                }
            }
            for q in [-10.0f64, 0.0, 45.0, 100.0] {
                let (a, b) = (
                    crate::leg::cylinder_length_at(&ours, q.to_radians()),
                    crate::leg::cylinder_length_at(&theirs, q.to_radians()),
                );
                assert!(close(a, b), "cylinder at {q}: {a} vs {b}");
            }
        }
    }
}
