//! `exoleg fmu`: the plant as an FMI 2.0 co-simulation FMU.

use super::*;

/// `exoleg fmu`.
pub(super) fn cmd_fmu(
    scenario: Option<PathBuf>,
    sets: Vec<String>,
    out: PathBuf,
    library: Option<PathBuf>,
) -> Result<i32> {
    let resolved = Scenario::load(scenario.as_deref(), &sets)?.resolve(&Resources::new())?;
    for w in &resolved.warnings {
        eprintln!("warning: {w}");
    }
    let library = library.or_else(crate::fmu::default_library).ok_or_else(|| {
        Error::Usage("cannot locate the FMU library next to this executable: pass --library PATH".into())
    })?;
    let mut inputs = crate::fsio::own_executable();
    inputs.extend(scenario);
    let r = crate::fmu::package(&resolved, &library, &out, &inputs)?;
    println!("wrote {} ({} bytes) from {}", out.display(), r.bytes, resolved.source_name);
    println!("GUID                {}", r.guid);
    println!(
        "outputs             {} (17 readings of the latest sample, the rest true_* time-series columns)",
        r.outputs
    );
    println!("input               valve_command (latched at the sample instants)");
    println!("parameters          {} (set before fmi2ExitInitializationMode)", r.parameters);
    println!("files in resources  {}", r.files);
    println!("communication step  {} s (the sample period: one reading and one command per step)", r.sample_period_s);
    Ok(EXIT_OK)
}
