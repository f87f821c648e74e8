//! `exoleg compare` (the paper's tables, and `--firmware`).

use super::*;

/// `exoleg compare`.
pub(super) fn cmd_compare(
    scenario: Option<PathBuf>,
    plant: Option<String>,
    json: Option<PathBuf>,
    sets: Vec<String>,
) -> Result<i32> {
    let mut all = Vec::new();
    if let Some(p) = plant {
        all.push(format!("plant.kind={p}"));
    }
    all.extend(sets);
    let base = Scenario::load(scenario.as_deref(), &all)?;
    let mut inputs = crate::fsio::own_executable();
    inputs.extend(base.resolve(&Resources::new()).map(|r| r.input_paths()).unwrap_or_default());
    inputs.extend(scenario);
    if let Some(p) = &json {
        crate::fsio::check_out(p, &compare::json_rule(&inputs))?;
    }
    let results = compare::run_cases(&base, &[])?;
    println!("Paper cases on plant `{:?}` ({}):", base.file.plant.kind, base.source_name);
    print!("{}", compare::table(&results));
    if let Some(p) = json {
        write_report(&p, &results, &inputs)?;
    }
    Ok(EXIT_OK)
}

/// Write a `--json` report (pretty JSON) under [`compare::json_rule`].
pub(super) fn write_report(path: &Path, value: &impl serde::Serialize, inputs: &[PathBuf]) -> Result<()> {
    let bytes = serde_json::to_vec_pretty(value)
        .map_err(|e| Error::Write { path: path.to_path_buf(), message: e.to_string() })?;
    crate::fsio::write_bytes(path, &compare::json_rule(inputs), &bytes).map(|_| ())
}

/// `exoleg compare --firmware`.
pub(super) fn cmd_firmware(json: Option<PathBuf>, sets: Vec<String>) -> Result<i32> {
    let inputs = crate::fsio::own_executable();
    if let Some(p) = &json {
        crate::fsio::check_out(p, &compare::json_rule(&inputs))?;
    }
    let rows = crate::study::firmware::run_table(&sets)?;
    println!(
        "Firmware conditions (1 kHz, zero-order hold, adc16, one sample of delay; bench cases at 0.1 ms steps).\n\
         Each cell: max |F_L - F_d| / max after settling / RMS after settling (N), and the knee RMS / max (deg) for gait:"
    );
    print!("{}", crate::study::firmware::table(&rows));
    if let Some(p) = json {
        write_report(&p, &rows, &inputs)?;
    }
    Ok(EXIT_OK)
}
