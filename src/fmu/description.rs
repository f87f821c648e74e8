//! `modelDescription.xml` (FMI 2.0 co-simulation) from the variable table.

use super::variables::{unit_factor, Causality, VarType, Variable, UNITS};
use super::MODEL_IDENTIFIER;
use std::fmt::Write;

/// What the description says besides the variables.
pub struct DescriptionInfo<'a> {
    /// `modelName`.
    pub model_name: &'a str,
    /// `guid` (changes with the resolved scenario).
    pub guid: &'a str,
    /// `DefaultExperiment/@stopTime` (s): the scenario's duration.
    pub stop_time_s: f64,
    /// `DefaultExperiment/@stepSize` (s): the sample period.
    pub step_size_s: f64,
}

/// Escape text for an XML attribute.
fn esc(s: &str) -> String {
    let mut o = String::with_capacity(s.len());
    for c in s.chars() {
        match c {
            '&' => o.push_str("&amp;"),
            '<' => o.push_str("&lt;"),
            '>' => o.push_str("&gt;"),
            '"' => o.push_str("&quot;"),
            '\'' => o.push_str("&apos;"),
            c if (c as u32) < 0x20 => o.push(' '),
            c => o.push(c),
        }
    }
    o
}

/// A number as XML Schema `double` that reads back bit-identical.
fn num(x: f64) -> String {
    format!("{x:?}")
}

fn header(o: &mut String, info: &DescriptionInfo) {
    let _ = writeln!(o, r#"<?xml version="1.0" encoding="UTF-8"?>"#);
    let _ = writeln!(
        o,
        r#"<fmiModelDescription fmiVersion="2.0" modelName="{}" guid="{}" description="exoleg: the scenario's leg, hydraulics, sensors, human and disturbances; the controller is the master's" generationTool="exoleg {}" variableNamingConvention="structured" numberOfEventIndicators="0">"#,
        esc(info.model_name),
        esc(info.guid),
        env!("CARGO_PKG_VERSION")
    );
    let _ = writeln!(
        o,
        r#"  <CoSimulation modelIdentifier="{MODEL_IDENTIFIER}" needsExecutionTool="false" canHandleVariableCommunicationStepSize="true" canInterpolateInputs="false" maxOutputDerivativeOrder="0" canRunAsynchronuously="false" canBeInstantiatedOnlyOncePerProcess="false" canNotUseMemoryManagementFunctions="true" canGetAndSetFMUstate="false" canSerializeFMUstate="false" providesDirectionalDerivative="false"/>"#
    );
    o.push_str("  <UnitDefinitions>\n");
    for (name, [kg, m, s, rad]) in UNITS {
        let mut base = String::new();
        for (k, e) in [("kg", kg), ("m", m), ("s", s), ("rad", rad)] {
            if e != 0 {
                let _ = write!(base, r#" {k}="{e}""#);
            }
        }
        let f = unit_factor(name);
        if f != 1.0 {
            let _ = write!(base, r#" factor="{}""#, num(f));
        }
        let _ = writeln!(o, r#"    <Unit name="{}"><BaseUnit{base}/></Unit>"#, esc(name));
    }
    o.push_str("  </UnitDefinitions>\n");
    o.push_str("  <LogCategories>\n");
    o.push_str("    <Category name=\"logStatusError\" description=\"refused calls and failed steps\"/>\n");
    o.push_str("    <Category name=\"logStatusWarning\" description=\"the scenario's warnings\"/>\n");
    o.push_str("    <Category name=\"logAll\" description=\"everything\"/>\n");
    o.push_str("  </LogCategories>\n");
    let _ = writeln!(
        o,
        r#"  <DefaultExperiment startTime="0.0" stopTime="{}" stepSize="{}"/>"#,
        num(info.stop_time_s),
        num(info.step_size_s)
    );
}

fn variable(o: &mut String, v: &Variable) {
    let (causality, variability, initial) = match v.causality {
        Causality::Parameter => ("parameter", "fixed", Some("exact")),
        Causality::CalculatedParameter => ("calculatedParameter", "fixed", Some("calculated")),
        Causality::Input => ("input", if v.ty == VarType::Real { "continuous" } else { "discrete" }, None),
        Causality::Output => ("output", "continuous", Some("calculated")),
    };
    let initial = initial.map(|i| format!(r#" initial="{i}""#)).unwrap_or_default();
    let _ = write!(
        o,
        r#"    <ScalarVariable name="{}" valueReference="{}" description="{}" causality="{causality}" variability="{variability}"{initial}>"#,
        esc(&v.name),
        v.vr,
        esc(&v.description)
    );
    let unit = if v.unit.is_empty() { String::new() } else { format!(r#" unit="{}""#, esc(v.unit)) };
    match (v.ty, v.start) {
        (VarType::Real, Some(s)) => {
            let _ = write!(o, r#"<Real start="{}"{unit}/>"#, num(s));
        }
        (VarType::Real, None) => {
            let _ = write!(o, r#"<Real{unit}/>"#);
        }
        (VarType::Integer, s) => {
            let start = s.map(|s| format!(r#" start="{}""#, s as i64)).unwrap_or_default();
            let _ = write!(o, r#"<Integer{start}/>"#);
        }
    }
    o.push_str("</ScalarVariable>\n");
}

/// The whole `modelDescription.xml`.
pub fn model_description(info: &DescriptionInfo, vars: &[Variable]) -> String {
    let mut o = String::new();
    header(&mut o, info);
    o.push_str("  <ModelVariables>\n");
    for v in vars {
        variable(&mut o, v);
    }
    o.push_str("  </ModelVariables>\n  <ModelStructure>\n    <Outputs>\n");
    // 1-based indices in ModelVariables. Outputs at a communication point do not depend on the
    // input set for the next step (no direct feedthrough: the command is held from then on).
    let outputs: Vec<usize> =
        vars.iter().enumerate().filter(|(_, v)| v.causality == Causality::Output).map(|(i, _)| i + 1).collect();
    for i in &outputs {
        let _ = writeln!(o, r#"      <Unknown index="{i}" dependencies=""/>"#);
    }
    o.push_str("    </Outputs>\n    <InitialUnknowns>\n");
    for (i, v) in vars.iter().enumerate() {
        if matches!(v.causality, Causality::Output | Causality::CalculatedParameter) {
            let _ = writeln!(o, r#"      <Unknown index="{}"/>"#, i + 1);
        }
    }
    o.push_str("    </InitialUnknowns>\n  </ModelStructure>\n</fmiModelDescription>\n");
    o
}
