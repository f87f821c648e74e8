//! An isolated plugin (`controller.plugin.isolate = true`): the plugin runs in a child process
//! (exoleg's own executable as `exoleg plugin-host`, [`child`]), which talks the wire
//! protocol ([`super::wire`]) with the run over a Unix `SOCK_SEQPACKET` socket pair: the
//! run's readings out, the plugin's command back, every sample. The same peer a board is
//! over UDP (`exoleg hil`), on another transport.
//!
//! Two watchdogs (FMPy's remoting has the first, not the second): the socket's end (the child
//! died: its signal or exit status is read with `waitpid`) and a wall-clock limit on every
//! call (`controller.plugin.timeout_s`: the child is killed). Either ends the run with
//! [`ControlStop`] (exit 3) naming the signal or the timeout, the call, the sample and the
//! simulated time; in a sweep only that run fails. The child is killed and reaped on every
//! path (`Drop`), and it dies with the thread that started it (`PR_SET_PDEATHSIG`), so no
//! zombie or orphan outlives a run.
//!
//! Cost: one round trip per sample (two context switches; the README gives the measured
//! figure and `benches/isolate.rs` measures it).

pub mod child;

use super::plugin::{message_text, output_of, readings_of, ExolegCommand, ExolegReadings, PluginSetup, StatusCount};
use super::wire::{self, Header, Message, MsgType};
use super::{ControlOutput, ControlStop, DiscreteController, SampleInput};
use std::io::{ErrorKind, Read, Write};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
use std::os::unix::net::UnixStream;
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// The hidden sub-command the child runs.
pub const HOST_COMMAND: &str = "plugin-host";
/// The time a child may take to start and create its instance on top of the call timeout (s).
pub const STARTUP_GRACE_S: f64 = 10.0;

/// How long either side polls for the other's answer, yielding the core at every look, before
/// it sleeps in the kernel (s). Measured (10,000 samples of ERL-SMC on the bench, 2 cores): on
/// an idle machine a sleeping peer wakes late (the round trip's p50 34 us with the host
/// sleeping at once, 53 us for the bare socket pair), polling both sides for 50 us gives 6.3 us
/// (7.5 us per sample all told); two isolated runs at once, 11 us each (12-15 us sleeping at
/// once): the yield gives the core away when another process needs it.
pub const SPIN_S: f64 = 50e-6;

/// Receive one datagram on `sock` without sleeping, polling for up to `spin` (yielding the
/// core between looks): None when nothing came (then block as usual).
pub fn receive_spinning(sock: &UnixStream, buf: &mut [u8], spin: Duration) -> Option<std::io::Result<usize>> {
    let t0 = Instant::now();
    loop {
        // SAFETY: `buf` is valid for writes of its length; the descriptor is the socket's.
        let n = unsafe { libc::recv(sock.as_raw_fd(), buf.as_mut_ptr().cast(), buf.len(), libc::MSG_DONTWAIT) };
        if n >= 0 {
            return Some(Ok(n as usize));
        }
        let e = std::io::Error::last_os_error();
        if e.kind() != ErrorKind::WouldBlock {
            return Some(Err(e));
        }
        if t0.elapsed() >= spin {
            return None;
        }
        std::thread::yield_now();
    }
}

/// One isolated plugin instance: a [`DiscreteController`] whose calls cross to the child.
pub struct IsolatedPlugin {
    setup: Arc<PluginSetup>,
    child: Option<Child>,
    sock: UnixStream,
    timeout: Duration,
    name: String,
    out: Vec<u8>,
    rx: Vec<u8>,
    command: ExolegCommand,
    status: StatusCount,
    /// The step call's wall time as the child measured it (s).
    compute_s: Vec<f64>,
    /// The whole round trip as the run saw it (s).
    round_trip_s: Vec<f64>,
}

/// What went wrong with the child, for the message.
enum Failure {
    /// The call took longer than the timeout.
    Timeout,
    /// The socket ended or broke (the child died or closed it).
    Gone(String),
    /// The child answered something else than the protocol asks.
    Protocol(String),
}

/// The executable to run as the plugin host: `EXOLEG_EXE` if set, this executable if it is
/// exoleg, else an `exoleg` next to it or one folder up (tests and benches in
/// `target/*/deps`).
pub fn host_executable() -> Result<PathBuf, String> {
    if let Some(p) = std::env::var_os("EXOLEG_EXE") {
        return Ok(PathBuf::from(p));
    }
    let me = std::env::current_exe().map_err(|e| format!("cannot find this executable: {e}"))?;
    if me.file_stem().is_some_and(|s| s == "exoleg") {
        return Ok(me);
    }
    for dir in me.ancestors().skip(1).take(2) {
        let c = dir.join("exoleg");
        if c.is_file() {
            return Ok(c);
        }
    }
    Err(format!(
        "controller.plugin.isolate runs the plugin in `exoleg {HOST_COMMAND}`, and no exoleg executable is next to {} (set EXOLEG_EXE)",
        me.display()
    ))
}

/// A connected `SOCK_SEQPACKET` pair, both ends close-on-exec.
fn seqpacket_pair() -> std::io::Result<(OwnedFd, OwnedFd)> {
    let mut fds = [0i32; 2];
    // SAFETY: socketpair writes two descriptors into `fds` on success.
    let r = unsafe { libc::socketpair(libc::AF_UNIX, libc::SOCK_SEQPACKET | libc::SOCK_CLOEXEC, 0, fds.as_mut_ptr()) };
    if r != 0 {
        return Err(std::io::Error::last_os_error());
    }
    // SAFETY: both descriptors are new and owned by nobody else.
    Ok(unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) })
}

/// Start `exoleg plugin-host` on the child's end of a socket pair.
fn spawn_host(setup: &PluginSetup, child_end: &OwnedFd) -> Result<Child, String> {
    let exe = host_executable()?;
    let fd = child_end.as_raw_fd();
    let parent = std::process::id() as libc::pid_t;
    let mut cmd = Command::new(&exe);
    cmd.arg(HOST_COMMAND).arg("--fd").arg(fd.to_string()).arg("--library").arg(&setup.library().path);
    cmd.stdin(Stdio::null());
    // SAFETY: the closure runs in the child between fork and exec and calls only
    // async-signal-safe functions (fcntl, prctl, getppid).
    unsafe {
        cmd.pre_exec(move || {
            // The child's end survives the exec (every other descriptor of ours does not).
            if libc::fcntl(fd, libc::F_SETFD, 0) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            // Die with the thread that started us; and if it is already gone, now.
            libc::prctl(libc::PR_SET_PDEATHSIG, libc::SIGKILL as libc::c_ulong);
            if libc::getppid() != parent {
                libc::_exit(1);
            }
            Ok(())
        });
    }
    cmd.spawn().map_err(|e| format!("cannot start {} {HOST_COMMAND}: {e}", exe.display()))
}

impl IsolatedPlugin {
    /// Start the child, say hello, send the run's figures and parameters, and wait for the
    /// instance (an error if the child does not start, or the plugin refuses its parameters).
    pub fn spawn(setup: Arc<PluginSetup>, timeout_s: f64) -> Result<Self, String> {
        let (ours, theirs) = seqpacket_pair().map_err(|e| format!("cannot make a socket pair: {e}"))?;
        let child = spawn_host(&setup, &theirs)?;
        drop(theirs);
        let name = format!("{} (isolated)", setup.library().name());
        let mut me = Self {
            status: StatusCount::new(name.clone()),
            setup,
            child: Some(child),
            sock: UnixStream::from(ours),
            timeout: Duration::from_secs_f64(timeout_s),
            name,
            out: Vec::with_capacity(wire::COMMAND_LEN + wire::HEADER_LEN),
            rx: vec![0; wire::MAX_DATAGRAM + 1],
            command: ExolegCommand::default(),
            compute_s: Vec::new(),
            round_trip_s: Vec::new(),
        };
        me.handshake().map_err(|f| me.describe(f, "the start (exoleg_create)", None))?;
        Ok(me)
    }

    /// HELLO in, SETUP out, READY in.
    fn handshake(&mut self) -> Result<(), Failure> {
        let startup = self.timeout + Duration::from_secs_f64(STARTUP_GRACE_S);
        let (_, hello) = self.receive(startup)?;
        match hello {
            Message::Hello { abi_version, channel_hash }
                if abi_version == wire::abi_version() && channel_hash == wire::channel_hash() => {}
            other => return Err(Failure::Protocol(format!("expected HELLO of this exoleg, got {other:?}"))),
        }
        let setup = Message::Setup(self.setup.wire_setup());
        self.send(&Header { kind: MsgType::Setup, seq: 0, sim_time_ns: 0 }, &setup)?;
        match self.receive(startup)?.1 {
            Message::Ready { status: 0, .. } => Ok(()),
            Message::Ready { message, .. } => Err(Failure::Protocol(message)),
            other => Err(Failure::Protocol(format!("expected READY, got {other:?}"))),
        }
    }

    fn send(&mut self, h: &Header, m: &Message) -> Result<(), Failure> {
        wire::encode(h, m, &mut self.out);
        match self.sock.write(&self.out) {
            Ok(n) if n == self.out.len() => Ok(()),
            Ok(n) => Err(Failure::Gone(format!("sent {n} of {} bytes", self.out.len()))),
            Err(e) => Err(Failure::Gone(e.to_string())),
        }
    }

    /// The next message, within `limit`.
    fn receive(&mut self, limit: Duration) -> Result<(Header, Message), Failure> {
        let spin = Duration::from_secs_f64(SPIN_S).min(limit);
        let got = match receive_spinning(&self.sock, &mut self.rx, spin) {
            Some(r) => r,
            None => {
                self.sock
                    .set_read_timeout(Some(limit.max(Duration::from_micros(1))))
                    .map_err(|e| Failure::Gone(e.to_string()))?;
                self.sock.read(&mut self.rx)
            }
        };
        match got {
            Ok(0) => Err(Failure::Gone("the socket closed".into())),
            Ok(n) => wire::decode(&self.rx[..n]).map_err(Failure::Protocol),
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => Err(Failure::Timeout),
            Err(e) => Err(Failure::Gone(e.to_string())),
        }
    }

    /// One sample across: READINGS out, the COMMAND of the same sample back.
    /// Returns the peer's status and the call it is from.
    fn exchange(&mut self, r: &ExolegReadings, seq: u64) -> Result<(i32, u32), Failure> {
        let h = Header { kind: MsgType::Readings, seq, sim_time_ns: wire::time_ns(r.t_s) };
        let t0 = Instant::now();
        self.send(&h, &Message::Readings(Box::new(*r)))?;
        let (h, m) = self.receive(self.timeout)?;
        self.round_trip_s.push(t0.elapsed().as_secs_f64());
        match m {
            Message::Command { status, call, compute_ns, command } if h.seq == seq => {
                self.command = *command;
                self.compute_s.push(compute_ns as f64 * 1e-9);
                Ok((status, call))
            }
            other => Err(Failure::Protocol(format!("expected the COMMAND of sample {seq}, got {other:?}"))),
        }
    }

    /// The message of a failure during `call` at `sample` (index, t), the child killed and
    /// reaped first (its signal or exit status named).
    fn describe(&mut self, f: Failure, call: &str, sample: Option<(u64, f64)>) -> String {
        let at = sample.map_or(String::new(), |(k, t)| format!(" of sample {k} (t = {t:.6} s)"));
        let timeout_s = self.timeout.as_secs_f64();
        let what = match f {
            Failure::Timeout => {
                self.kill();
                format!("took longer than controller.plugin.timeout_s = {timeout_s} s in {call}{at}: killed")
            }
            Failure::Gone(why) => match self.reap(Duration::from_secs(2)) {
                Some(status) => format!("{} in {call}{at}", exit_text(status)),
                None => format!("stopped answering in {call}{at} ({why}): killed"),
            },
            Failure::Protocol(why) => {
                self.kill();
                format!("broke the protocol in {call}{at}: {why}")
            }
        };
        format!("plugin {} {what}", self.name)
    }

    /// Wait up to `limit` for the child to end; kill it after that. Its status if it ended by
    /// itself.
    fn reap(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let child = self.child.as_mut()?;
        let t0 = Instant::now();
        loop {
            match child.try_wait() {
                Ok(Some(s)) => {
                    self.child = None;
                    return Some(s);
                }
                Ok(None) if t0.elapsed() < limit => std::thread::sleep(Duration::from_micros(200)),
                _ => {
                    self.kill();
                    return None;
                }
            }
        }
    }

    /// Kill the child and reap it (nothing if it is gone).
    fn kill(&mut self) {
        if let Some(mut c) = self.child.take() {
            let _ = c.kill();
            let _ = c.wait();
        }
    }
}

/// How a child ended, in words: the signal by name, or the exit status.
pub fn exit_text(s: std::process::ExitStatus) -> String {
    match (s.signal(), s.code()) {
        (Some(sig), _) => format!("was killed by signal {sig} ({})", signal_name(sig)),
        (None, Some(code)) => format!("exited with status {code} (an exit() in the plugin?)"),
        (None, None) => format!("ended ({s})"),
    }
}

/// A signal's name (`SIGSEGV`), or `signal N`.
pub fn signal_name(sig: i32) -> String {
    let known = [
        (libc::SIGSEGV, "SIGSEGV, segmentation fault"),
        (libc::SIGABRT, "SIGABRT, abort"),
        (libc::SIGBUS, "SIGBUS, bus error"),
        (libc::SIGFPE, "SIGFPE, arithmetic exception"),
        (libc::SIGILL, "SIGILL, illegal instruction"),
        (libc::SIGKILL, "SIGKILL"),
        (libc::SIGTERM, "SIGTERM"),
        (libc::SIGINT, "SIGINT"),
        (libc::SIGTRAP, "SIGTRAP"),
        (libc::SIGSYS, "SIGSYS, bad system call"),
        (libc::SIGPIPE, "SIGPIPE"),
        (libc::SIGXCPU, "SIGXCPU"),
    ];
    known.iter().find(|(n, _)| *n == sig).map_or_else(|| format!("signal {sig}"), |(_, s)| s.to_string())
}

impl DiscreteController for IsolatedPlugin {
    fn kind(&self) -> &str {
        "plugin"
    }

    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        let seq = if s.period_s > 0.0 { (s.t_s / s.period_s).round() as u64 } else { 0 };
        if self.child.is_none() {
            return Err(ControlStop { message: format!("plugin {} is no longer running", self.name) });
        }
        let r = readings_of(s);
        let (st, call) = self
            .exchange(&r, seq)
            .map_err(|f| ControlStop { message: self.describe(f, "exoleg_step", Some((seq, s.t_s))) })?;
        let cmd = self.command;
        let call = if call == wire::CALL_RESET { "exoleg_reset" } else { "exoleg_step" };
        self.status.take(call, st, || message_text(&cmd.message))?;
        output_of(&self.status.name, &self.command, st)
    }

    fn log_names(&self) -> Vec<String> {
        self.setup.log_names().to_vec()
    }

    fn log_values(&self, out: &mut [f64]) {
        for (o, v) in out.iter_mut().zip(self.command.log) {
            *o = v;
        }
    }

    fn warnings(&self) -> (usize, Option<String>) {
        (self.status.warnings, self.status.last_warning.clone())
    }

    fn compute_times_s(&self) -> &[f64] {
        &self.compute_s
    }

    fn link_report(&self) -> Option<serde_json::Value> {
        let rt = super::timing::TimingStats::json(&self.round_trip_s)?;
        Some(serde_json::json!({ "transport": "isolated (unix seqpacket)", "round_trip": rt }))
    }
}

impl Drop for IsolatedPlugin {
    /// BYE (the child destroys its instance and exits), then the child reaped: killed if it
    /// has not ended within a second.
    fn drop(&mut self) {
        if self.child.is_some() {
            let _ = self.sock.set_write_timeout(Some(Duration::from_millis(100)));
            let bye = Message::Bye { status: 0, message: String::new() };
            let _ = self.send(&Header { kind: MsgType::Bye, seq: 0, sim_time_ns: 0 }, &bye);
            self.reap(Duration::from_secs(1));
        }
    }
}
