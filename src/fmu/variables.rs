//! The FMU's variables: one table, built from the resolved scenario the same way when the FMU
//! is packaged (`modelDescription.xml`) and when it runs (value references to values).

use crate::control::READINGS;
use crate::record::Layout;
use crate::sim::Model;

/// FMI base type of a variable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum VarType {
    /// `fmi2Real` (f64).
    Real,
    /// `fmi2Integer` (i32).
    Integer,
}

/// FMI causality (with the variability and initial it implies here).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Causality {
    /// Set before initialization (`variability="fixed"`, `initial="exact"`).
    Parameter,
    /// Computed from the parameters at initialization (`fixed`, `calculated`).
    CalculatedParameter,
    /// Set by the master at communication points (`continuous`, start 0).
    Input,
    /// Computed by the FMU (`continuous`, `calculated`; no direct feedthrough).
    Output,
}

/// What a variable's value is.
#[derive(Debug, Clone, PartialEq)]
pub enum Role {
    /// A controller reading of the latest sample: index in [`READINGS`].
    Reading(usize),
    /// A column of `timeseries.csv` at the communication point: index in `layout.names()`.
    Truth(usize),
    /// The valve command u (input).
    ValveCommand,
    /// A scenario key the master may set before initialization.
    Param(&'static str),
    /// The controller's nominal model: index in [`NOMINAL`].
    Nominal(usize),
}

/// One FMU variable.
#[derive(Debug, Clone, PartialEq)]
pub struct Variable {
    /// Name (structured naming: `hydraulics.beta_pa`, `true_load_force_n`).
    pub name: String,
    /// Value reference (unique within its [`VarType`]).
    pub vr: u32,
    /// Base type.
    pub ty: VarType,
    /// Causality.
    pub causality: Causality,
    /// What it is.
    pub role: Role,
    /// SI unit ("" for none).
    pub unit: &'static str,
    /// Description.
    pub description: String,
    /// Start value (parameters and the input).
    pub start: Option<f64>,
}

/// The scenario keys an FMU offers as parameters (with the scenario's values as start values):
/// (key, unit, integer?, description). A key the scenario does not hold as a number is left out.
pub const PARAMETERS: [(&str, &str, bool, &str); 18] = [
    ("seed", "", true, "seed of the sensor noise and the disturbances"),
    ("sensors.delay_samples", "", true, "transport delay of the readings, in samples"),
    ("hydraulics.beta_pa", "Pa", false, "effective bulk modulus of the oil"),
    ("hydraulics.v0_m3", "m3", false, "dead volume of a chamber"),
    ("hydraulics.k_q", "", false, "valve flow gain"),
    ("hydraulics.k_c", "", false, "valve flow-pressure coefficient"),
    ("hydraulics.leakage", "", false, "cylinder leakage coefficient"),
    ("hydraulics.tau_s", "s", false, "spool time constant"),
    ("hydraulics.k_s", "m", false, "spool gain per unit command"),
    ("hydraulics.supply_pressure_pa", "Pa", false, "supply pressure"),
    ("friction.coulomb_n", "N", false, "seal Coulomb friction"),
    ("friction.static_n", "N", false, "seal static friction"),
    ("friction.viscous_n_s_per_m", "N.s/m", false, "seal viscous friction"),
    ("leg.mass_scale", "", false, "scale on every link mass and inertia of the leg"),
    ("human.k_p", "", false, "interaction force gain on the force error (w1 = k_p e + k_d e_dot)"),
    ("human.k_d", "", false, "interaction force gain on the force error's rate"),
    ("disturbance.state_gain_force", "", false, "state-dependent disturbance gain on the force"),
    ("disturbance.state_gain_force_rate", "", false, "state-dependent disturbance gain on the force rate"),
];

/// The nominal model a controller inverts (`controller.nominal` over `[hydraulics]`):
/// (name, unit, description).
pub const NOMINAL: [(&str, &str, &str); 5] = [
    ("nominal.n1", "N/m", "dF/dt = n1 x_v - n2 v - n3 F: spool gain"),
    ("nominal.n2", "N/m", "piston velocity gain"),
    ("nominal.n3", "1/s", "force decay rate"),
    ("nominal.tau_s", "s", "spool time constant"),
    ("nominal.k_s", "m", "spool position per unit command"),
];

/// The nominal model's values, in the order of [`NOMINAL`].
pub fn nominal_values(m: &Model) -> [f64; 5] {
    let c = &m.nominal.c;
    [c.n1, c.n2, c.n3, c.tau_s, c.k_s]
}

/// Value references of each group start here (readings at 0).
const TRUTH_VR: u32 = 100;
const INPUT_VR: u32 = 1000;
const PARAM_VR: u32 = 2000;
const NOMINAL_VR: u32 = 3000;

/// Units of the time-series columns, from their suffixes.
fn column_unit(name: &str) -> &'static str {
    const SUFFIXES: [(&str, &str); 12] = [
        ("_n_per_s2", "N/s2"),
        ("_n_per_s", "N/s"),
        ("_deg_s", "deg/s"),
        ("_deg", "deg"),
        ("_m_s", "m/s"),
        ("_nm", "N.m"),
        ("_n", "N"),
        ("_m", "m"),
        ("_rad_s", "rad/s"),
        ("_rad", "rad"),
        ("_s", "s"),
        ("_w", "W"),
    ];
    SUFFIXES.iter().find(|(s, _)| name.ends_with(s)).map_or("", |(_, u)| *u)
}

/// Look up a dotted key's number in the scenario as a table.
fn number_at(table: &toml::Table, key: &str) -> Option<f64> {
    let mut parts = key.split('.');
    let mut v = table.get(parts.next()?)?;
    for p in parts {
        v = v.as_table()?.get(p)?;
    }
    v.as_float().or_else(|| v.as_integer().map(|i| i as f64))
}

/// The FMU's variables for a resolved scenario (`table`: its file as TOML) whose run records
/// `layout`. The same scenario always gives the same table.
pub fn variables(table: &toml::Table, layout: &Layout, leg: bool) -> Vec<Variable> {
    let mut v = Vec::new();
    for (i, r) in READINGS.iter().enumerate() {
        v.push(Variable {
            name: r.name.to_string(),
            vr: i as u32,
            ty: VarType::Real,
            causality: Causality::Output,
            role: Role::Reading(i),
            unit: r.unit,
            description: format!("reading: {} (latest sample)", r.description),
            start: None,
        });
    }
    for (i, c) in layout.names().iter().enumerate() {
        if c == "t_s" || c.starts_with("log_") {
            continue;
        }
        v.push(Variable {
            name: format!("true_{c}"),
            vr: TRUTH_VR + i as u32,
            ty: VarType::Real,
            causality: Causality::Output,
            role: Role::Truth(i),
            unit: column_unit(c),
            description: format!("timeseries.csv column {c} at the communication point"),
            start: None,
        });
    }
    v.push(Variable {
        name: "valve_command".into(),
        vr: INPUT_VR,
        ty: VarType::Real,
        causality: Causality::Input,
        role: Role::ValveCommand,
        unit: "",
        description: "valve command u, latched at the sample instants (k_s u is the commanded spool position)".into(),
        start: Some(0.0),
    });
    for (i, (key, unit, integer, doc)) in PARAMETERS.iter().enumerate() {
        if key.starts_with("leg.") && !leg {
            continue;
        }
        let Some(x) = number_at(table, key) else { continue };
        if *integer && !(0.0..=i32::MAX as f64).contains(&x) {
            continue;
        }
        v.push(Variable {
            name: key.to_string(),
            vr: PARAM_VR + i as u32,
            ty: if *integer { VarType::Integer } else { VarType::Real },
            causality: Causality::Parameter,
            role: Role::Param(key),
            unit,
            description: doc.to_string(),
            start: Some(x),
        });
    }
    for (i, (name, unit, doc)) in NOMINAL.iter().enumerate() {
        v.push(Variable {
            name: name.to_string(),
            vr: NOMINAL_VR + i as u32,
            ty: VarType::Real,
            causality: Causality::CalculatedParameter,
            role: Role::Nominal(i),
            unit,
            description: doc.to_string(),
            start: None,
        });
    }
    v
}

/// Every unit the variables use, for `UnitDefinitions`: (name, SI base-unit exponents kg, m,
/// s, rad).
pub const UNITS: [(&str, [i32; 4]); 18] = [
    ("s", [0, 0, 1, 0]),
    ("1/s", [0, 0, -1, 0]),
    ("N", [1, 1, -2, 0]),
    ("N/s", [1, 1, -3, 0]),
    ("N/s2", [1, 1, -4, 0]),
    ("N/m", [1, 0, -2, 0]),
    ("N.s/m", [1, 0, -1, 0]),
    ("N.m", [1, 2, -2, 0]),
    ("m", [0, 1, 0, 0]),
    ("m/s", [0, 1, -1, 0]),
    ("m/s2", [0, 1, -2, 0]),
    ("m3", [0, 3, 0, 0]),
    ("Pa", [1, -1, -2, 0]),
    ("W", [1, 2, -3, 0]),
    ("rad", [0, 0, 0, 1]),
    ("rad/s", [0, 0, -1, 1]),
    ("deg", [0, 0, 0, 1]),
    ("deg/s", [0, 0, -1, 1]),
];

/// The factor of a unit to its base units (degrees are radians times pi/180).
pub fn unit_factor(unit: &str) -> f64 {
    if unit.starts_with("deg") {
        std::f64::consts::PI / 180.0
    } else {
        1.0
    }
}
