//! `exoleg hil`: the plant against a controller peer over UDP.

use super::*;

/// `exoleg hil`: the scenario's plant against a controller peer over UDP. Everything is
/// checked before the port opens (the flags, the scenario, what goes to the peer, `--out`).
pub(super) fn cmd_hil(
    scenario: Option<PathBuf>,
    sets: Vec<String>,
    opts: crate::hil::HilOptions,
    out: PathBuf,
    quiet: bool,
) -> Result<i32> {
    opts.check().map_err(|(flag, e)| Error::input(flag, "", e))?;
    let sc = Scenario::load(scenario.as_deref(), &sets)?.resolve(&Resources::new())?;
    warn(&sc.warnings);
    let m = &sc.model;
    if m.sample_every.is_none() {
        let why = "a controller peer runs sampled: set controller.sample_period_s > 0";
        return Err(Error::input(&sc.source_name, "controller.sample_period_s", why));
    }
    // The same check of what the peer gets as a plugin's, on every route.
    let plugin = &sc.file.controller.plugin;
    plugin.check().map_err(|(k, e)| Error::input(&sc.source_name, k, e))?;
    let c = &m.nominal.c;
    let params = plugin.numbers().map_err(|(k, e)| Error::input(&sc.source_name, k, e))?;
    let setup = crate::control::plugin::InstanceSetup {
        sample_period_s: m.sample_period_s,
        valve_command_limit: m.valve_limit.0,
        nominal: [c.n1, c.n2, c.n3, c.tau_s, c.k_s],
        seed: m.seed,
        params: params.into_iter().map(|(n, v)| (n.to_string_lossy().into_owned(), v)).collect(),
    };
    let dir = crate::output::OutputDir::prepare_with_inputs(&out, "--out", &sc.input_paths())?;
    let link = crate::hil::HilController::bind(&opts).map_err(|e| Error::input("--listen", "", e))?;
    let at = link.local_addr();
    let shown = at.map_or(opts.listen.clone(), |a| a.to_string());
    eprintln!("exoleg hil: waiting for a controller peer on {shown} ({:?})", opts.mode);
    if at.is_some_and(|a| !a.ip().is_loopback()) && opts.allow_from.is_empty() {
        eprintln!(
            "warning: --listen {shown} is reachable beyond this machine and the protocol is unauthenticated: \
             whoever says HELLO first drives the valve (give --allow-from ADDR, or listen on 127.0.0.1)"
        );
    }
    let stopped = |message| Error::ControllerStopped { time_s: 0.0, controller: "hil".into(), message };
    let ctrl = crate::hil::HilController::on_link(link, &setup, plugin.log.clone(), opts).map_err(stopped)?;
    let driver = ctrl.peer_name();
    eprintln!("exoleg hil: {driver} drives this run");
    let report = study::RunBuilder::new(&sc).controller(Box::new(ctrl)).write_into(dir)?;
    if !quiet {
        print_summary(&sc, &report.summary, &out, Some(&driver));
        if let Some(l) = &report.summary.controller_link {
            println!("link                {l}");
        }
    }
    warn_controller_stop(&report.summary);
    verdict(&sc, &report)
}
