//! The firmware's modelled computation (issue 36): `controller.compute_delay_s` delays each
//! command by whole steps, exactly as the fault campaign's overrun does for a whole sample; a
//! seeded jitter against a budget gives overruns that the policy applies late, drops or stops
//! on; no key, no change.

use exoleg::record::{MemoryRecord, Row};
use exoleg::session::run_simulation;
use exoleg::Simulation;

const BASE: [&str; 4] =
    ["controller.kind=\"erl_smc\"", "controller.sample_period_s=0.001", "sim.dt_s=0.0001", "sim.duration_s=0.5"];

fn run(extra: &[&str]) -> exoleg::Result<(exoleg::metrics::Summary, MemoryRecord)> {
    let sets: Vec<&str> = BASE.iter().chain(extra).copied().collect();
    let sc = exoleg::load(None, &sets)?;
    let mut rec = MemoryRecord::default();
    let (summary, _) = run_simulation(Simulation::new(sc.model.clone())?, &mut rec)?;
    Ok((summary, rec))
}

fn truth(r: &Row) -> String {
    format!("{:?}", Row { fault_active: false, ..r.clone() })
}

/// A delay of one sample period is the overrun fault of one sample: every row the same (the
/// last row's command aside: there the delayed command of the last sample has taken effect).
/// A delay of 0 is no delay, bit for bit; a shorter delay costs less (measured: largest force
/// error 99.4 N, 124.5 N with 0.3 ms, 158.1 N with 1 ms).
#[test]
fn a_delay_of_one_sample_is_the_overrun_fault_and_zero_is_nothing() {
    let (s0, r0) = run(&[]).unwrap();
    let (_, rz) = run(&["controller.compute_delay_s=0.0"]).unwrap();
    assert_eq!(r0.rows, rz.rows);
    let (s1, r1) = run(&["controller.compute_delay_s=0.001"]).unwrap();
    let (_, rf) = run(&["faults=[{target=\"controller\", kind=\"overrun\", samples=1, onset_s=0.0}]"]).unwrap();
    let n = r1.rows.len();
    for (a, b) in r1.rows[..n - 1].iter().zip(&rf.rows[..n - 1]) {
        assert_eq!(truth(a), truth(b), "t = {}", a.t_s);
    }
    let (s3, _) = run(&["controller.compute_delay_s=0.0003"]).unwrap();
    let e = |s: &exoleg::metrics::Summary| s.max_abs_force_error_n;
    assert!(e(&s0) < e(&s3) && e(&s3) < e(&s1), "{} {} {}", e(&s0), e(&s3), e(&s1));
    let m = s3.compute_model.unwrap();
    assert_eq!(
        (m["samples"].as_u64(), m["max_delay_steps"].as_u64(), m["overruns"].as_u64()),
        (Some(500), Some(3), Some(0))
    );
}

/// 0.4 ms + up to 0.8 ms of seeded jitter against a 1 ms budget: a quarter of the samples
/// overrun (measured 128 of 500; the limits are 3 sd of the binomial), the same for the same
/// seed; `hold` drops exactly those, `apply_late` none; `stop` ends the run, exit 3 through the
/// CLI, naming the overrun.
#[test]
fn overruns_of_the_budget_follow_the_policy() {
    let jitter = [
        "controller.compute_delay_s=0.0004",
        "controller.compute_jitter_s=0.0008",
        "controller.compute_budget_s=0.001",
    ];
    let (late, rl) = run(&jitter).unwrap();
    let (late2, rl2) = run(&jitter).unwrap();
    assert_eq!(rl.rows, rl2.rows);
    let m = late.compute_model.clone().unwrap();
    let overruns = m["overruns"].as_u64().unwrap();
    assert!((96..=154).contains(&overruns), "{m}");
    assert_eq!(m["dropped"].as_u64(), Some(0));
    assert_eq!(late.compute_model, late2.compute_model);
    let hold: Vec<&str> = jitter.iter().copied().chain(["controller.overrun_policy=\"hold\""]).collect();
    let (held, _) = run(&hold).unwrap();
    let h = held.compute_model.unwrap();
    assert_eq!((h["overruns"].as_u64(), h["dropped"].as_u64()), (Some(overruns), Some(overruns)));
    let stop: Vec<&str> = jitter.iter().copied().chain(["controller.overrun_policy=\"stop\""]).collect();
    let e = run(&stop).unwrap_err();
    assert_eq!(e.exit_code(), 3);
    assert!(e.to_string().contains("compute budget overrun"), "{e}");
    let e = exoleg::load(None, &["controller.compute_delay_s=0.001"]).err().unwrap();
    assert!(e.to_string().contains("controller.compute_delay_s") && e.exit_code() == 2, "{e}");
}
