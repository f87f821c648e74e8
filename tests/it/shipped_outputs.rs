//! The shipped scenarios' `timeseries.csv`, byte for byte. Recorded before the structure
//! redesign (issue 8) and the hardening (issue 10); a refactor must leave these unchanged, and
//! a deliberate change of the numbers updates a hash here with the reason in the commit.

use sha2::{Digest, Sha256};
use std::path::Path;
use std::process::Command;

const EXPECTED: [(&str, &str); 7] = [
    ("default", "1c4693823ccff2c6bdb7cc539e59d8c7cc79e416697c8d1486e3c45dd250df52"),
    ("gait_walk", "e36ae981be589c20fd5fe8a036caece32571f43da0e5076ad0059f672b7828dc"),
    ("gait_walk_fast", "f4de96ddbeac72cde510e1bee3366511858fd577c880277247887064fdbf4a1f"),
    ("paper_10hz_gamma200", "74c22657231e2ef80831ec8b5b6057cbedfbe0b500b5f59789dd5793a38f385c"),
    ("paper_10hz_gamma300", "814806aa8c7c34483868a89b6441064002bf264a183ccab5508bc0bb67a5fef8"),
    ("paper_2hz_gamma100", "4d2288b14a36198ad62a4f72887dd318270ad33fd15db751b8b631cce1a23e28"),
    ("paper_2hz_gamma200", "f95cd1aac3031b84dd9b08319d850256bd709fae503b79fe9d96823eb8a36b90"),
];

#[test]
fn shipped_scenarios_give_the_recorded_timeseries() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("assets/scenarios");
    let tmp = tempfile::tempdir().unwrap();
    let mut wrong = Vec::new();
    for (name, hash) in EXPECTED {
        let out = tmp.path().join(name);
        let o = Command::new(env!("CARGO_BIN_EXE_exoleg"))
            .args(["run", "--quiet", "--out"])
            .arg(&out)
            .arg(dir.join(format!("{name}.toml")))
            .output()
            .unwrap();
        assert!(o.status.success(), "{name}: {}", String::from_utf8_lossy(&o.stderr));
        let got = format!("{:x}", Sha256::digest(std::fs::read(out.join("timeseries.csv")).unwrap()));
        if got != hash {
            wrong.push(format!("{name}: {got}"));
        }
    }
    assert!(wrong.is_empty(), "changed time series:\n{}", wrong.join("\n"));
}
