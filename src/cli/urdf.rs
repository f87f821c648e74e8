//! `exoleg urdf`: the built-in leg scaled to a subject.

use super::*;

/// `exoleg urdf`: the subject goes through the scenario's own checks.
pub(super) fn cmd_urdf(
    mass_kg: f64,
    height_m: f64,
    leg_length_m: Option<f64>,
    sex: String,
    out: PathBuf,
) -> Result<i32> {
    let sex_toml = toml::Value::String(sex).to_string();
    let mut sets = vec![format!("subject={{mass_kg={mass_kg:?}, height_m={height_m:?}, sex={sex_toml}}}")];
    if let Some(l) = leg_length_m {
        sets.push(format!("subject.leg_length_m={l:?}"));
    }
    let sc = Scenario::load(None, &sets)?;
    let subject = sc.file.subject.as_ref().ok_or_else(|| Error::Usage("no subject".into()))?;
    let text = crate::leg::subject::scaled_urdf(&subject.body());
    crate::leg::LegSpec::from_urdf_with(&text, &crate::leg::LegOptions::default())
        .map_err(|e| Error::input("exoleg urdf", "--height-m", format!("the scaled leg does not build: {e}")))?;
    if out.as_os_str() == "-" {
        print!("{text}");
    } else {
        let inputs = crate::fsio::own_executable();
        let rule = crate::fsio::OutFile {
            flag: "--out",
            what: "a URDF exoleg urdf wrote",
            inputs: &inputs,
            ours: crate::leg::subject::is_scaled_urdf,
        };
        crate::fsio::write_bytes(&out, &rule, text.as_bytes())?;
        eprintln!("wrote {}", out.display());
    }
    Ok(EXIT_OK)
}
