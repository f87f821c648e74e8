//! Issue 42, the out-of-process routes: a board link no stranger can drive (class 2), lockstep
//! that gives up (3), runs that survive a pause (4), no orphans (5), one validation for every
//! route (8), messages that name the call that hung (9), and the small ones (11: a plugin's
//! own raise(SIGSEGV), a memory cap, a peer's compute time). Each test names the class it
//! covers; each failed before the fix.

use crate::common::{build_plugin, exe};
use exoleg::control::plugin::ExolegCommand;
use exoleg::control::wire::{self, Header, Message, MsgType};
use std::io::{BufRead, BufReader};
use std::net::UdpSocket;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

const ROOT: &str = env!("CARGO_MANIFEST_DIR");
const SCENARIO: &str = "assets/scenarios/paper_2hz_gamma100.toml";
/// The ERL-SMC comparison's settings (tests/it/hil.rs).
const SETS: [&str; 4] = [
    "controller.sample_period_s=0.001",
    "controller.plugin.params={k=100.0, delta=15.0, zeta=10.0}",
    "sensors.preset=\"adc16\"",
    "sensors.delay_samples=1",
];

fn stderr(o: &Output) -> String {
    String::from_utf8_lossy(&o.stderr).into_owned()
}

fn sets_args(extra: &[&str]) -> Vec<String> {
    SETS.iter().chain(extra).flat_map(|s| ["--set".to_string(), s.to_string()]).collect()
}

/// The C client linked with erl_smc.c (its own build: the EINTR retry of exoleg_hil.c).
fn hil_client() -> PathBuf {
    static EXE: std::sync::OnceLock<(tempfile::TempDir, PathBuf)> = std::sync::OnceLock::new();
    EXE.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let exe = dir.path().join("hil_erl_smc");
        let o = Command::new("cc")
            .args(["-O2", "-ffp-contract=off", "-I", "include", "-o"])
            .arg(&exe)
            .args(["examples/hil/hil_client.c", "examples/hil/exoleg_hil.c", "examples/c_controller/erl_smc.c", "-lm"])
            .current_dir(ROOT)
            .output()
            .unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        (dir, exe)
    })
    .1
    .clone()
}

/// A running `exoleg hil`: the child, its port, and its stderr read in the background.
struct Hil {
    child: Child,
    port: u16,
    rest: Option<std::thread::JoinHandle<String>>,
    first: String,
}

impl Hil {
    /// `exoleg hil` listening on `listen` (port 0) with `args` and the comparison's settings.
    fn start(out: &Path, listen: &str, args: &[&str], extra_sets: &[&str]) -> Self {
        let mut cmd = Command::new(exe());
        cmd.args(["hil", SCENARIO, "--quiet", "--listen", listen, "--out"]).arg(out).args(args);
        cmd.args(sets_args(extra_sets)).current_dir(ROOT).stdout(Stdio::piped()).stderr(Stdio::piped());
        let mut child = cmd.spawn().unwrap();
        let mut err = BufReader::new(child.stderr.take().unwrap());
        let mut line = String::new();
        err.read_line(&mut line).unwrap();
        let port = line.trim().split(" on ").nth(1).and_then(|a| a.split(' ').next()?.rsplit_once(':')?.1.parse().ok());
        let port = port.unwrap_or_else(|| panic!("no port in {line:?}"));
        let rest = std::thread::spawn(move || {
            let mut s = String::new();
            let _ = std::io::Read::read_to_string(&mut err, &mut s);
            s
        });
        Self { child, port, rest: Some(rest), first: line }
    }

    /// Its exit code and stderr (killed after `limit`: the test fails).
    fn finish(mut self, limit: Duration) -> (Option<i32>, String) {
        let status = wait_limited(&mut self.child, limit);
        let rest = self.rest.take().unwrap().join().unwrap();
        (status, format!("{}{rest}", self.first))
    }
}

/// Wait for `child` at most `limit`; killed after it and the test fails.
fn wait_limited(child: &mut Child, limit: Duration) -> Option<i32> {
    let t0 = Instant::now();
    loop {
        if let Some(s) = child.try_wait().unwrap() {
            return s.code();
        }
        if t0.elapsed() > limit {
            let _ = child.kill();
            let _ = child.wait();
            panic!("hung for {limit:?}");
        }
        std::thread::sleep(Duration::from_millis(10));
    }
}

fn summary(dir: &Path) -> serde_json::Value {
    serde_json::from_slice(&std::fs::read(dir.join("summary.json")).unwrap()).unwrap()
}

/// The in-process plugin's time series of the comparison (with `extra` settings).
fn in_process(tmp: &Path, extra: &[&str]) -> Vec<u8> {
    let lib = build_plugin("examples/c_controller/erl_smc.c", "include");
    let out = tmp.join("in_process");
    let lib_set = format!("controller.plugin.library=\"{}\"", lib.display());
    let mut args =
        vec!["run".to_string(), "--quiet".into(), "--out".into(), out.display().to_string(), SCENARIO.into()];
    let mut sets = vec!["controller.kind=\"plugin\"", &lib_set];
    sets.extend(extra);
    args.extend(sets_args(&sets));
    let o = Command::new(exe()).args(&args).current_dir(ROOT).output().unwrap();
    assert!(o.status.success(), "{}", stderr(&o));
    std::fs::read(out.join("timeseries.csv")).unwrap()
}

fn signal(pid: u32, sig: i32) {
    // SAFETY: kill(2) on a child of this test.
    assert_eq!(unsafe { libc::kill(pid as i32, sig) }, 0);
}

/// A peer (or a stranger) made of a Rust socket.
struct Peer {
    sock: UdpSocket,
    buf: Vec<u8>,
}

impl Peer {
    fn bound() -> Self {
        let sock = UdpSocket::bind("127.0.0.1:0").unwrap();
        sock.set_read_timeout(Some(Duration::from_secs(5))).unwrap();
        Self { sock, buf: vec![0; 70000] }
    }
    fn to(port: u16) -> Self {
        let p = Self::bound();
        p.sock.connect(("127.0.0.1", port)).unwrap();
        p
    }
    fn port(&self) -> u16 {
        self.sock.local_addr().unwrap().port()
    }
    fn send(&self, kind: MsgType, seq: u64, m: &Message) {
        let mut out = Vec::new();
        wire::encode(&Header { kind, seq, sim_time_ns: 0 }, m, &mut out);
        let _ = self.sock.send(&out);
    }
    fn hello(&self) {
        self.send(
            MsgType::Hello,
            0,
            &Message::Hello { abi_version: wire::abi_version(), channel_hash: wire::channel_hash() },
        );
    }
    fn receive(&mut self) -> Option<(Header, Message)> {
        let n = self.sock.recv(&mut self.buf).ok()?;
        wire::decode(&self.buf[..n]).ok()
    }
    fn handshake(&mut self) {
        self.hello();
        assert!(matches!(self.receive(), Some((_, Message::Setup(_)))));
        self.send(MsgType::Ready, 0, &Message::Ready { status: 0, message: String::new() });
    }
    fn command(&self, seq: u64, u: f64, compute_ns: u64) {
        let command = Box::new(ExolegCommand { valve_command: u, ..Default::default() });
        self.send(MsgType::Command, seq, &Message::Command { status: 0, call: 0, compute_ns, command });
    }
    fn refuse_in_the_peers_name(&self) {
        self.send(MsgType::Ready, 0, &Message::Ready { status: 2, message: "a stranger says no".into() });
    }
}

/// Class 2. A stranger on another port, with the C client as the peer: before the handshake
/// (its READY refusing the instance and COMMANDs driving the valve at 1e6, queued behind the
/// client's HELLO while exoleg is stopped), during it and after it (COMMANDs for every sample):
/// the run is the in-process plugin's bit for bit, the stranger's datagrams counted as
/// `strangers`, and exoleg names the peer that drove it. Before: "the peer ... could not create
/// its instance: a stranger says no" (exit 3).
#[test]
fn hil_drops_a_strangers_datagrams_before_during_and_after_the_handshake() {
    let tmp = tempfile::tempdir().unwrap();
    let reference = in_process(tmp.path(), &[]);
    let out = tmp.path().join("stranger");
    let hil = Hil::start(&out, "127.0.0.1:0", &["--mode", "lockstep"], &[]);
    signal(hil.child.id(), libc::SIGSTOP);
    let client = Command::new(hil_client()).args(["127.0.0.1", &hil.port.to_string()]).stdout(Stdio::piped()).spawn();
    let client = client.unwrap();
    std::thread::sleep(Duration::from_millis(300));
    let stranger = Peer::to(hil.port);
    stranger.refuse_in_the_peers_name();
    for k in 0..20 {
        stranger.command(k, 1e6, 0);
    }
    std::thread::sleep(Duration::from_millis(300));
    signal(hil.child.id(), libc::SIGCONT);
    let during = std::thread::spawn(move || {
        for k in 0..1000 {
            stranger.command(k, 1e6, 0);
            std::thread::sleep(Duration::from_micros(200));
        }
        stranger
    });
    let c = client.wait_with_output().unwrap();
    let (code, err) = hil.finish(Duration::from_secs(60));
    let stranger = during.join().unwrap();
    stranger.command(1000, 1e6, 0); // after the run: nobody listens
    assert!(c.status.success(), "client: {}", String::from_utf8_lossy(&c.stderr));
    assert_eq!(code, Some(0), "{err}");
    assert!(err.contains("drives this run"), "{err}");
    assert!(std::fs::read(out.join("timeseries.csv")).unwrap() == reference, "the stranger changed the run");
    let link = summary(&out)["controller_link"].clone();
    assert!(link["strangers"].as_u64().unwrap() >= 21, "{link}");
}

/// Class 2 and 9. With `--allow-from` only that address may be the peer: a stranger's HELLO
/// first is dropped and counted, the allowed peer drives the run, and the report names it
/// (not the scenario's built-in controller). Listening beyond loopback without it warns that
/// the protocol is unauthenticated. Before: the stranger became the controller; `--allow-from`
/// did not exist; no warning.
#[test]
fn hil_allow_from_admits_only_the_named_peer_and_wide_listening_warns() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("allowed");
    let mut peer = Peer::bound();
    let allow = format!("127.0.0.1:{}", peer.port());
    let mut cmd = Command::new(exe());
    cmd.args(["hil", SCENARIO, "--listen", "127.0.0.1:0", "--allow-from", &allow, "--out"]).arg(&out);
    cmd.args(sets_args(&["sim.duration_s=0.05"])).current_dir(ROOT).stdout(Stdio::piped()).stderr(Stdio::piped());
    let mut child = cmd.spawn().unwrap();
    let mut err = BufReader::new(child.stderr.take().unwrap());
    let mut line = String::new();
    err.read_line(&mut line).unwrap();
    let port: u16 = line
        .trim()
        .split(" on ")
        .nth(1)
        .unwrap()
        .split(' ')
        .next()
        .unwrap()
        .rsplit_once(':')
        .unwrap()
        .1
        .parse()
        .unwrap();
    let stranger = Peer::to(port);
    stranger.hello();
    std::thread::sleep(Duration::from_millis(100));
    peer.sock.connect(("127.0.0.1", port)).unwrap();
    peer.handshake();
    while let Some((h, m)) = peer.receive() {
        match m {
            Message::Readings(_) => peer.command(h.seq, 0.0, 0),
            Message::Bye { .. } => break,
            _ => {}
        }
    }
    let code = wait_limited(&mut child, Duration::from_secs(20));
    let mut rest = String::new();
    std::io::Read::read_to_string(&mut err, &mut rest).unwrap();
    let mut stdout = String::new();
    std::io::Read::read_to_string(&mut child.stdout.take().unwrap(), &mut stdout).unwrap();
    assert_eq!(code, Some(0), "{rest}");
    let name = format!("HIL peer 127.0.0.1:{}", peer.port());
    assert!(rest.contains(&format!("{name} drives this run")), "{rest}");
    assert!(stdout.contains(&format!("controller          {name}")), "{stdout}");
    let link = summary(&out)["controller_link"].clone();
    assert_eq!(link["peer"], format!("127.0.0.1:{}", peer.port()), "{link}");
    assert!(link["strangers"].as_u64().unwrap() >= 1, "{link}");
    // Beyond loopback without --allow-from: a warning; a bad --allow-from: exit 2.
    let wide = Hil::start(&tmp.path().join("wide"), "0.0.0.0:0", &["--wait-s", "0.3"], &[]);
    let (code, err) = wide.finish(Duration::from_secs(10));
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("unauthenticated") && err.contains("--allow-from"), "{err}");
    let o = Command::new(exe()).args(["hil", "--allow-from", "nowhere"]).current_dir(ROOT).output().unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", stderr(&o));
    assert!(stderr(&o).contains("--allow-from"), "{}", stderr(&o));
}

/// Class 3. A peer that answers 10 samples, then repeats its last COMMAND (and says HELLO)
/// every 20 ms instead of answering: the resend timer runs from the last READINGS and the stall
/// watchdog from the last valid COMMAND whatever arrives, so the run ends (exit 3, the stall
/// watchdog named, READINGS resent meanwhile) after --stall-timeout-s. Before: it hung.
#[test]
fn hil_lockstep_gives_up_on_a_peer_repeating_its_last_command() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("repeat");
    let hil = Hil::start(&out, "127.0.0.1:0", &["--stall-timeout-s", "1.0", "--resend-s", "0.05"], &[]);
    let mut peer = Peer::to(hil.port);
    peer.handshake();
    for _ in 0..10 {
        let (h, _) = peer.receive().unwrap();
        peer.command(h.seq, 0.0, 0);
    }
    let t0 = Instant::now();
    let chatter = std::thread::spawn(move || {
        while t0.elapsed() < Duration::from_secs(4) {
            peer.command(9, 0.0, 0);
            peer.hello();
            std::thread::sleep(Duration::from_millis(20));
        }
    });
    let (code, err) = hil.finish(Duration::from_secs(10));
    let took = t0.elapsed();
    chatter.join().unwrap();
    assert_eq!(code, Some(3), "{err}");
    assert!(err.contains("stall watchdog") && err.contains("at sample 10"), "{err}");
    let resends: u64 = err.split(" resends").next().unwrap().rsplit(' ').next().unwrap().parse().unwrap();
    assert!(resends >= 10, "{resends} resends: {err}");
    assert!(took < Duration::from_secs(3), "{took:?}");
}

/// Class 3 and 6. The HIL durations have ranges: a resend of 1 ns (a flood that never reads
/// the answer), and 1e300 s for any of them (before: a panic converting it, exit 101), are
/// exit 2 naming the flag, before anything listens.
#[test]
fn hil_durations_have_ranges() {
    for (flag, v) in [
        ("--resend-s", "1e-9"),
        ("--resend-s", "1e300"),
        ("--wait-s", "1e300"),
        ("--stall-timeout-s", "1e300"),
        ("--wait-s", "0"),
    ] {
        let o = Command::new(exe())
            .args(["hil", SCENARIO, "--listen", "127.0.0.1:0", "--out", "/nonexistent/x", flag, v])
            .args(sets_args(&[]))
            .current_dir(ROOT)
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{flag} {v}: {e}");
        assert!(e.contains(flag) && !e.contains("waiting for a controller peer"), "{flag} {v}: {e}");
    }
}

/// Class 9. `exoleg hil` checks --out before its port opens (before: after the board had
/// created its instance); its logged names and parameters are checked as a plugin's (class 8:
/// before, 9 names were taken and the ninth column was zeros).
#[test]
fn hil_checks_out_and_what_goes_to_the_peer_before_listening() {
    let tmp = tempfile::tempdir().unwrap();
    let foreign = tmp.path().join("foreign");
    std::fs::create_dir(&foreign).unwrap();
    std::fs::write(foreign.join("notes.txt"), "mine").unwrap();
    let nine = "controller.plugin.log=[\"a\",\"b\",\"c\",\"d\",\"e\",\"f\",\"g\",\"h\",\"i\"]";
    let long = format!("controller.plugin.params={{{}=1.0}}", "n".repeat(300));
    for (out, sets, want) in [
        (foreign.clone(), vec![], "--out"),
        (tmp.path().join("a"), vec![nine.to_string()], "controller.plugin.log"),
        (tmp.path().join("b"), vec![long], "controller.plugin.params.nnnn"),
    ] {
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let o = Command::new(exe())
            .args(["hil", SCENARIO, "--listen", "127.0.0.1:0", "--wait-s", "0.3", "--out"])
            .arg(&out)
            .args(sets_args(&sets))
            .current_dir(ROOT)
            .output()
            .unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{want}: {e}");
        assert!(e.contains(want) && !e.contains("waiting for a controller peer"), "{want}: {e}");
    }
}

/// The crashy plugin at a path of this test's own (its processes are found by it).
fn own_crashy(dir: &Path, tag: &str) -> PathBuf {
    let lib = dir.join(format!("libcrashy_{tag}.so"));
    std::fs::copy(build_plugin("tests/plugins/crashy.c", "include"), &lib).unwrap();
    lib
}

fn plugin_sets(lib: &Path, extra: &[String]) -> Vec<String> {
    let mut v = vec![
        "controller.kind=\"plugin\"".to_string(),
        "controller.sample_period_s=0.001".into(),
        format!("controller.plugin.library=\"{}\"", lib.display()),
    ];
    v.extend(extra.iter().cloned());
    v.into_iter().flat_map(|s| ["--set".to_string(), s]).collect()
}

/// `exoleg run` of the crashy plugin with `extra` settings.
fn crashy_run(lib: &Path, out: &Path, extra: &[&str]) -> Command {
    let mut cmd = Command::new(exe());
    cmd.args(["run", "--quiet", "--out"]).arg(out).arg(SCENARIO);
    let extra: Vec<String> = extra.iter().map(|s| s.to_string()).collect();
    cmd.args(plugin_sets(lib, &extra)).current_dir(ROOT);
    cmd
}

/// Processes (pid) whose command line mentions `needle`, other than this test's.
fn processes_mentioning(needle: &str) -> Vec<u32> {
    let mut out = Vec::new();
    for e in std::fs::read_dir("/proc").unwrap().flatten() {
        let Ok(pid) = e.file_name().to_string_lossy().parse::<u32>() else { continue };
        let Ok(cmd) = std::fs::read(e.path().join("cmdline")) else { continue };
        if pid != std::process::id() && String::from_utf8_lossy(&cmd).contains(needle) {
            out.push(pid);
        }
    }
    out
}

fn assert_none_left(needle: &str) {
    let t0 = Instant::now();
    while !processes_mentioning(needle).is_empty() && t0.elapsed() < Duration::from_secs(2) {
        std::thread::sleep(Duration::from_millis(20));
    }
    assert_eq!(processes_mentioning(needle), Vec::<u32>::new(), "processes left running with {needle}");
}

/// Class 4. One stop and continue of 1.5 s (longer than the plugin's 1 s timeout) in the
/// middle of an isolated run, of a sweep of isolated runs and of a HIL lockstep run (the C
/// client as the peer), each while exoleg waits for its controller: each completes (exit 0;
/// the HIL run still the in-process plugin's bit for bit). Before: exit 3 "... stopped
/// answering ... (Interrupted system call (os error 4))".
#[test]
fn isolated_hil_and_sweep_runs_survive_a_pause() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = own_crashy(tmp.path(), "pause");
    let pause = |child: &mut Child, after: Duration| {
        std::thread::sleep(after);
        assert!(child.try_wait().unwrap().is_none(), "the run ended before its pause");
        signal(child.id(), libc::SIGSTOP);
        std::thread::sleep(Duration::from_millis(1500));
        signal(child.id(), libc::SIGCONT);
    };
    // An isolated run: 150 samples of 20 ms each (exoleg waits in its receive when stopped).
    let out = tmp.path().join("isolated");
    let sets = ["controller.plugin.isolate=true", "controller.plugin.params={busy_us=20000.0}", "sim.duration_s=0.15"];
    let mut child = crashy_run(&lib, &out, &sets).stderr(Stdio::piped()).spawn().unwrap();
    pause(&mut child, Duration::from_millis(600));
    let code = wait_limited(&mut child, Duration::from_secs(60));
    let mut e = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut e).unwrap();
    assert_eq!(code, Some(0), "isolated: {e}");
    // A sweep of 4 isolated runs on 2 workers.
    let out = tmp.path().join("sweep");
    let mut cmd = Command::new(exe());
    cmd.args([
        "sweep",
        SCENARIO,
        "--quiet",
        "--jobs",
        "2",
        "--grid",
        "controller.plugin.params.gain=1e-6,2e-6,3e-6,4e-6",
    ]);
    cmd.arg("--out").arg(&out).args(plugin_sets(
        &lib,
        &[
            "controller.plugin.isolate=true".into(),
            "controller.plugin.params.busy_us=20000.0".into(),
            "sim.duration_s=0.1".into(),
        ],
    ));
    let mut child = cmd.current_dir(ROOT).stderr(Stdio::piped()).spawn().unwrap();
    pause(&mut child, Duration::from_millis(600));
    let code = wait_limited(&mut child, Duration::from_secs(120));
    let mut e = String::new();
    std::io::Read::read_to_string(&mut child.stderr.take().unwrap(), &mut e).unwrap();
    assert_eq!(code, Some(0), "sweep: {e}");
    let lines = std::fs::read_to_string(out.join("runs.jsonl")).unwrap();
    assert_eq!(lines.lines().filter(|l| l.contains("\"passed\":true")).count(), 4, "{lines}");
    // HIL lockstep with the C client sleeping 0-4 ms before every reply (about 2 s).
    let reference = in_process(tmp.path(), &[]);
    let out = tmp.path().join("hil");
    let mut hil = Hil::start(&out, "127.0.0.1:0", &["--mode", "lockstep"], &[]);
    let knobs = ["--sleep", "1.0", "0.004", "--seed", "3"];
    let mut client = Command::new(hil_client());
    client.args(["127.0.0.1", &hil.port.to_string()]).args(knobs).stdout(Stdio::piped());
    let client = client.spawn().unwrap();
    pause(&mut hil.child, Duration::from_millis(300));
    let c = client.wait_with_output().unwrap();
    let (code, err) = hil.finish(Duration::from_secs(60));
    assert!(c.status.success(), "client: {}", String::from_utf8_lossy(&c.stderr));
    assert_eq!(code, Some(0), "hil: {err}");
    assert!(std::fs::read(out.join("timeseries.csv")).unwrap() == reference, "the paused HIL run differs");
    assert_none_left(&lib.display().to_string());
}

/// Class 5. A plugin that forks a grandchild (which sleeps 30 s holding the socket) leaves no
/// process after its run; one that forks and then segfaults is reported as the segfault at
/// once, not as a timeout after the whole timeout_s. Before: the grandchild outlived the run,
/// and the crash read "took longer than controller.plugin.timeout_s = 5 s".
#[test]
fn a_forking_plugin_leaves_no_process_and_its_crash_is_seen_at_once() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = own_crashy(tmp.path(), "fork");
    let out = tmp.path().join("fork");
    let o = crashy_run(
        &lib,
        &out,
        &["controller.plugin.isolate=true", "controller.plugin.params={crash=7}", "sim.duration_s=0.05"],
    )
    .output()
    .unwrap();
    assert_eq!(o.status.code(), Some(0), "{}", stderr(&o));
    assert_none_left(&lib.display().to_string());
    let t0 = Instant::now();
    let o = crashy_run(
        &lib,
        &tmp.path().join("fork_crash"),
        &[
            "controller.plugin.isolate=true",
            "controller.plugin.timeout_s=5.0",
            "controller.plugin.params={crash=8}",
            "sim.duration_s=0.05",
        ],
    )
    .output()
    .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{e}");
    assert!(e.contains("SIGSEGV") && e.contains("exoleg_step of sample 5"), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(3), "{:?}: {e}", t0.elapsed());
    assert_none_left(&lib.display().to_string());
}

/// Class 8. Parameters whose SETUP outgrows a datagram, and a name longer than the wire's
/// 255 bytes, are refused the same way in-process and isolated (exit 2 naming the key, before
/// the run). Before: in-process accepted them; isolated blamed the plugin ("broke the
/// protocol") or cut the name on the wire.
#[test]
fn every_route_refuses_the_same_parameters_naming_the_key() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = own_crashy(tmp.path(), "params");
    let many: Vec<String> = (0..200).map(|i| format!("p{i:03}_{}=1.0", "x".repeat(200))).collect();
    let many = format!("controller.plugin.params={{{}}}", many.join(", "));
    let long = format!("controller.plugin.params={{{}=1.0}}", "n".repeat(300));
    for (sets, want) in [(many, "datagram"), (long, "1..=255 bytes")] {
        for isolate in ["false", "true"] {
            let iso = format!("controller.plugin.isolate={isolate}");
            let o = crashy_run(&lib, &tmp.path().join("p"), &[&sets, &iso, "sim.duration_s=0.01"]).output().unwrap();
            let e = stderr(&o);
            assert_eq!(o.status.code(), Some(2), "{want} isolate={isolate}: {e}");
            assert!(e.contains("controller.plugin.params") && e.contains(want), "{want} isolate={isolate}: {e}");
        }
    }
}

/// Class 9. A hang in exoleg_reset is named exoleg_reset (before: exoleg_step), and a hang in
/// exoleg_create says what it waited, timeout_s plus the start-up grace (before: it waited
/// timeout_s + 10 s and said timeout_s).
#[test]
fn a_hang_names_the_call_and_the_time_it_waited() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = own_crashy(tmp.path(), "hang");
    // A hang at the first sample ends the run (exit 3); one in exoleg_create, before the run,
    // is the instance's failure to be made (exit 2, as a plugin refusing its parameters).
    let run = |crash: i32, timeout: &str, code: i32| {
        let p = format!("controller.plugin.params={{crash={crash}}}");
        let t = format!("controller.plugin.timeout_s={timeout}");
        let o = crashy_run(&lib, &tmp.path().join("h"), &["controller.plugin.isolate=true", &t, &p]).output().unwrap();
        assert_eq!(o.status.code(), Some(code), "{}", stderr(&o));
        stderr(&o)
    };
    let e = run(9, "0.3", 3);
    assert!(e.contains("took longer than controller.plugin.timeout_s = 0.3 s in exoleg_reset of sample 0"), "{e}");
    let e = run(10, "0.2", 2);
    assert!(
        e.contains("took longer than 10.2 s (controller.plugin.timeout_s = 0.2 s and 10 s to start the child) in the start (exoleg_create)"),
        "{e}"
    );
    assert_none_left(&lib.display().to_string());
}

/// Class 11. A plugin that raises SIGSEGV itself (once, as a firmware fault handler does) ends
/// its isolated run at that sample (before: the Rust runtime's handler returned, the plugin
/// went on and the run completed); a leaking isolated plugin under controller.plugin.memory_mb
/// ends only its run, the message naming the limit; memory_mb out of range or without
/// isolation is exit 2.
#[test]
fn a_raised_sigsegv_kills_the_child_and_memory_mb_caps_a_leak() {
    let tmp = tempfile::tempdir().unwrap();
    let lib = own_crashy(tmp.path(), "small");
    let o = crashy_run(
        &lib,
        &tmp.path().join("r"),
        &["controller.plugin.isolate=true", "controller.plugin.params={crash=6}"],
    )
    .output()
    .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{e}");
    assert!(e.contains("SIGSEGV") && e.contains("sample 5 (t = 0.005000 s)"), "{e}");
    let t0 = Instant::now();
    let o = crashy_run(
        &lib,
        &tmp.path().join("leak"),
        &[
            "controller.plugin.isolate=true",
            "controller.plugin.memory_mb=256",
            "controller.plugin.params={crash=5, at_s=0.0}",
        ],
    )
    .output()
    .unwrap();
    let e = stderr(&o);
    assert_eq!(o.status.code(), Some(3), "{e}");
    assert!(e.contains("controller.plugin.memory_mb = 256"), "{e}");
    assert!(t0.elapsed() < Duration::from_secs(10), "{:?}", t0.elapsed());
    for (sets, want) in [
        (vec!["controller.plugin.isolate=true", "controller.plugin.memory_mb=1"], "must be"),
        (vec!["controller.plugin.memory_mb=256"], "isolate = true"),
        (vec!["controller.plugin.isolate=true", "controller.plugin.timeout_s=1e300"], "controller.plugin.timeout_s"),
    ] {
        let o = crashy_run(&lib, &tmp.path().join("bad"), &sets).output().unwrap();
        let e = stderr(&o);
        assert_eq!(o.status.code(), Some(2), "{want}: {e}");
        assert!(e.contains(want), "{want}: {e}");
    }
    assert_none_left(&lib.display().to_string());
}

/// Class 11. A HIL peer that reports a compute time of u64::MAX ns: what the summary keeps is
/// at most the sample's round trip (counted as `compute_clamped`). Before: 1.8e10 s.
#[test]
fn a_hil_peer_cannot_report_more_compute_than_its_round_trip() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("compute");
    let hil = Hil::start(&out, "127.0.0.1:0", &[], &["sim.duration_s=0.05"]);
    let mut peer = Peer::to(hil.port);
    peer.handshake();
    while let Some((h, m)) = peer.receive() {
        match m {
            Message::Readings(_) => peer.command(h.seq, 0.0, u64::MAX),
            Message::Bye { .. } => break,
            _ => {}
        }
    }
    let (code, err) = hil.finish(Duration::from_secs(20));
    assert_eq!(code, Some(0), "{err}");
    let js = summary(&out);
    let max = js["controller_compute"]["max_s"].as_f64().unwrap();
    let rt = js["controller_link"]["round_trip"]["max_s"].as_f64().unwrap();
    assert!(max <= rt, "compute {max} s beyond the round trip {rt} s");
    assert_eq!(js["controller_link"]["compute_clamped"], 50, "{js}");
}
