//! An isolated plugin (`controller.plugin.isolate = true`): the plugin runs in a child process
//! (exoleg's own executable as `exoleg plugin-host`, [`child`]), which talks the wire
//! protocol ([`super::wire`]) with the run over a Unix `SOCK_SEQPACKET` socket pair: the
//! run's readings out, the plugin's command back, every sample. The same peer a board is
//! over UDP (`exoleg hil`), on another transport.
//!
//! Two watchdogs (FMPy's remoting has the first, not the second): the child's end (seen by
//! waiting for the child itself, not only by its socket, which a process the plugin forked may
//! hold open: its signal or exit status is read with `waitid`) and a wall-clock limit on every
//! call (`controller.plugin.timeout_s`; the run's own pauses, a Ctrl-Z or a debugger, do not
//! count: [`super::wait`]): the child is killed. Either ends the run with [`ControlStop`]
//! (exit 3) naming the signal or the timeout, the call, the sample and the simulated time; in
//! a sweep only that run fails. The child runs in a process group of its own, killed and
//! reaped on every path (`Drop`), what the plugin forked with it, and it dies with the thread
//! that started it (`PR_SET_PDEATHSIG`), so no zombie or orphan outlives a run (a plugin that
//! leaves the group, `setsid()`, is on its own).
//!
//! Cost: one round trip per sample (two context switches; the README gives the measured
//! figure and `benches/isolate.rs` measures it).

pub mod child;

use super::plugin::{message_text, output_of, readings_of, ExolegCommand, PluginSetup, StatusCount};
use super::wire::{self, Header, Message, MsgType};
use super::{ControlOutput, ControlStop, DiscreteController, SampleInput};
use std::io::{ErrorKind, Write};
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
    memory_mb: Option<u64>,
    name: String,
    out: Vec<u8>,
    rx: Vec<u8>,
    command: ExolegCommand,
    status: StatusCount,
    /// `exoleg_reset` has been called (at the first sample).
    reset_done: bool,
    /// The call the child is in while the run waits (for messages).
    call: &'static str,
    /// The step call's wall time as the child measured it (s).
    compute_s: Vec<f64>,
    /// The whole round trip as the run saw it (s).
    round_trip_s: Vec<f64>,
}

/// What went wrong with the child, for the message.
enum Failure {
    /// The call took longer than this (the run's own pauses not counted).
    Timeout(Duration),
    /// The socket ended or broke, or the child ended.
    Gone(String),
    /// The child answered something else than the protocol asks.
    Protocol(String),
}

/// How often a wait for the child looks whether it is still alive (a grandchild may hold the
/// socket open after the child died).
const WATCH_SLICE: Duration = Duration::from_millis(10);

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

/// Start `exoleg plugin-host` on the child's end of a socket pair, in a process group of its
/// own (whatever the plugin forks is killed with it: [`IsolatedPlugin::end_child`]).
fn spawn_host(setup: &PluginSetup, child_end: &OwnedFd, memory_mb: Option<u64>) -> Result<Child, String> {
    let exe = host_executable()?;
    let fd = child_end.as_raw_fd();
    let parent = std::process::id() as libc::pid_t;
    let mut cmd = Command::new(&exe);
    cmd.arg(HOST_COMMAND).arg("--fd").arg(fd.to_string()).arg("--library").arg(&setup.library().path);
    if let Some(mb) = memory_mb {
        cmd.arg("--memory-mb").arg(mb.to_string());
    }
    cmd.stdin(Stdio::null());
    // Its own process group: the run kills the group, the plugin's own children with it.
    cmd.process_group(0);
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

/// Wait up to `limit` for `fd` to be readable (or hung up): Ok(false) when the time ran out.
fn readable(fd: i32, limit: Duration) -> std::io::Result<bool> {
    let mut p = libc::pollfd { fd, events: libc::POLLIN, revents: 0 };
    let ts = libc::timespec { tv_sec: limit.as_secs() as libc::time_t, tv_nsec: limit.subsec_nanos() as _ };
    // SAFETY: one valid pollfd and a valid timespec for the call's duration.
    let r = unsafe { libc::ppoll(&mut p, 1, &ts, std::ptr::null()) };
    match r {
        0 => Ok(false),
        n if n > 0 => Ok(true),
        _ => Err(std::io::Error::last_os_error()),
    }
}

impl IsolatedPlugin {
    /// Start the child, say hello, send the run's figures and parameters, and wait for the
    /// instance (an error if the child does not start, or the plugin refuses its parameters).
    pub fn spawn(setup: Arc<PluginSetup>, limits: super::plugin::Isolation) -> Result<Self, String> {
        let (ours, theirs) = seqpacket_pair().map_err(|e| format!("cannot make a socket pair: {e}"))?;
        let child = spawn_host(&setup, &theirs, limits.memory_mb)?;
        drop(theirs);
        let name = format!("{} (isolated)", setup.library().name());
        let mut me = Self {
            status: StatusCount::new(name.clone()),
            setup,
            child: Some(child),
            sock: UnixStream::from(ours),
            timeout: Duration::from_secs_f64(limits.timeout_s),
            memory_mb: limits.memory_mb,
            name,
            out: Vec::with_capacity(wire::COMMAND_LEN + wire::HEADER_LEN),
            rx: vec![0; wire::MAX_DATAGRAM + 1],
            command: ExolegCommand::default(),
            reset_done: false,
            call: "the start (loading the library)",
            compute_s: Vec::new(),
            round_trip_s: Vec::new(),
        };
        me.handshake().map_err(|f| me.describe(f, None))?;
        Ok(me)
    }

    /// The time the child may take to start and create its instance: the call timeout plus
    /// [`STARTUP_GRACE_S`].
    fn startup(&self) -> Duration {
        self.timeout + Duration::from_secs_f64(STARTUP_GRACE_S)
    }

    /// HELLO in, SETUP out, READY in.
    fn handshake(&mut self) -> Result<(), Failure> {
        let (_, hello) = self.receive(self.startup())?;
        match hello {
            Message::Hello { abi_version, channel_hash }
                if abi_version == wire::abi_version() && channel_hash == wire::channel_hash() => {}
            other => return Err(Failure::Protocol(format!("expected HELLO of this exoleg, got {other:?}"))),
        }
        let setup = Message::Setup(self.setup.wire_setup());
        self.call = "the start (exoleg_create)";
        self.send(&Header { kind: MsgType::Setup, seq: 0, sim_time_ns: 0 }, &setup)?;
        match self.receive(self.startup())?.1 {
            Message::Ready { status: 0, .. } => Ok(()),
            Message::Ready { message, .. } => Err(Failure::Protocol(message)),
            other => Err(Failure::Protocol(format!("expected READY, got {other:?}"))),
        }
    }

    fn send(&mut self, h: &Header, m: &Message) -> Result<(), Failure> {
        wire::encode(h, m, &mut self.out);
        loop {
            match self.sock.write(&self.out) {
                Ok(n) if n == self.out.len() => return Ok(()),
                Ok(n) => return Err(Failure::Gone(format!("sent {n} of {} bytes", self.out.len()))),
                Err(e) if e.kind() == ErrorKind::Interrupted => continue,
                Err(e) => return Err(Failure::Gone(e.to_string())),
            }
        }
    }

    /// The next message, within `limit` (the run's own pauses not counted); the child's end
    /// seen by waiting for it, not only by its socket.
    fn receive(&mut self, limit: Duration) -> Result<(Header, Message), Failure> {
        let mut spin = Duration::from_secs_f64(SPIN_S).min(limit);
        let fd = self.sock.as_raw_fd();
        let mut deadline = super::wait::Deadline::new(limit);
        loop {
            if let Some(got) = receive_spinning(&self.sock, &mut self.rx, spin) {
                return match got {
                    Ok(0) => Err(Failure::Gone("the socket closed".into())),
                    Ok(n) => wire::decode(&self.rx[..n]).map_err(Failure::Protocol),
                    Err(e) => Err(Failure::Gone(e.to_string())),
                };
            }
            spin = Duration::ZERO;
            let slice = deadline.left().min(WATCH_SLICE);
            let t0 = Instant::now();
            let r = readable(fd, slice);
            let interrupted = matches!(&r, Err(e) if e.kind() == ErrorKind::Interrupted);
            if super::wait::was_paused(t0, slice, interrupted) {
                deadline.restart();
            }
            match r {
                Ok(true) => continue,
                Err(e) if !interrupted => return Err(Failure::Gone(e.to_string())),
                _ => {}
            }
            if self.child_ended() {
                return Err(Failure::Gone("the child process ended".into()));
            }
            if deadline.passed() {
                return Err(Failure::Timeout(limit));
            }
        }
    }

    /// The child's COMMAND of sample `seq` for `call` (its status, the command kept).
    fn reply(&mut self, seq: u64, call: u32) -> Result<i32, Failure> {
        let (h, m) = self.receive(self.timeout)?;
        match m {
            Message::Command { status, call: c, compute_ns, command } if h.seq == seq && c == call => {
                self.command = *command;
                if call == wire::CALL_STEP {
                    self.compute_s.push(compute_ns as f64 * 1e-9);
                }
                Ok(status)
            }
            other => Err(Failure::Protocol(format!("expected the COMMAND of sample {seq}, got {other:?}"))),
        }
    }

    /// One sample across: READINGS out; at the first sample the reset's COMMAND back (its
    /// status taken as in-process: a warning counted, a stop the end); the step's COMMAND back.
    fn exchange(&mut self, s: &SampleInput, seq: u64) -> Result<i32, ControlStop> {
        let r = readings_of(s);
        let h = Header { kind: MsgType::Readings, seq, sim_time_ns: wire::time_ns(r.t_s) };
        let t0 = Instant::now();
        let at = Some((seq, s.t_s));
        self.send(&h, &Message::Readings(Box::new(r))).map_err(|f| ControlStop::crash(self.describe(f, at)))?;
        if !self.reset_done {
            self.reset_done = true;
            self.call = "exoleg_reset";
            let st = self.reply(seq, wire::CALL_RESET).map_err(|f| ControlStop::crash(self.describe(f, at)))?;
            let cmd = self.command;
            self.status.take("exoleg_reset", st, || message_text(&cmd.message))?;
        }
        self.call = "exoleg_step";
        let st = self.reply(seq, wire::CALL_STEP).map_err(|f| ControlStop::crash(self.describe(f, at)))?;
        self.round_trip_s.push(t0.elapsed().as_secs_f64());
        Ok(st)
    }

    /// The message of a failure during the current call at `sample` (index, t), the child and
    /// its process group killed and reaped first (its signal or exit status named).
    fn describe(&mut self, f: Failure, sample: Option<(u64, f64)>) -> String {
        let at = sample.map_or(String::new(), |(k, t)| format!(" of sample {k} (t = {t:.6} s)"));
        let call = self.call;
        let timeout_s = self.timeout.as_secs_f64();
        let what = match f {
            Failure::Timeout(limit) => {
                self.end_child(Duration::ZERO);
                if limit == self.timeout {
                    format!("took longer than controller.plugin.timeout_s = {timeout_s} s in {call}{at}: killed")
                } else {
                    format!(
                        "took longer than {} s (controller.plugin.timeout_s = {timeout_s} s and {STARTUP_GRACE_S} s to start the child) in {call}{at}: killed",
                        limit.as_secs_f64()
                    )
                }
            }
            Failure::Gone(why) => match self.end_child(Duration::from_secs(2)) {
                Some(status) => format!("{}{} in {call}{at}", exit_text(status), self.memory_hint(status)),
                None => format!("stopped answering in {call}{at} ({why}): killed"),
            },
            Failure::Protocol(why) => {
                self.end_child(Duration::ZERO);
                format!("broke the protocol in {call}{at}: {why}")
            }
        };
        format!("plugin {} {what}", self.name)
    }

    /// With `controller.plugin.memory_mb`, a crash may be an allocation the limit refused.
    fn memory_hint(&self, status: std::process::ExitStatus) -> String {
        match (self.memory_mb, status.signal()) {
            (Some(mb), Some(libc::SIGSEGV | libc::SIGABRT | libc::SIGBUS | libc::SIGKILL)) => {
                format!(" (controller.plugin.memory_mb = {mb}: an allocation beyond the limit?)")
            }
            _ => String::new(),
        }
    }

    /// Whether the child has ended (not reaped: its process group stays named by its pid
    /// until [`Self::end_child`] kills the group).
    fn child_ended(&self) -> bool {
        let Some(c) = &self.child else { return true };
        // SAFETY: zeroed siginfo is valid for waitid to fill; WNOWAIT leaves the child unreaped.
        let mut info: libc::siginfo_t = unsafe { std::mem::zeroed() };
        let flags = libc::WEXITED | libc::WNOHANG | libc::WNOWAIT;
        // SAFETY: a child of this process; `info` is valid for writes.
        let r = unsafe { libc::waitid(libc::P_PID, c.id() as libc::id_t, &mut info, flags) };
        // SAFETY: si_pid is set by waitid (0 when the child has not changed state).
        r != 0 || unsafe { info.si_pid() } != 0
    }

    /// Wait up to `limit` for the child to end by itself, then kill its process group (the
    /// child, or what it forked) and reap it. Its status if it ended by itself.
    fn end_child(&mut self, limit: Duration) -> Option<std::process::ExitStatus> {
        let t0 = Instant::now();
        while !self.child_ended() && t0.elapsed() < limit {
            std::thread::sleep(Duration::from_micros(200));
        }
        let by_itself = self.child_ended();
        let mut child = self.child.take()?;
        // SAFETY: kill(2) on the child's process group (its pid: `process_group(0)`), which
        // exists until the child is reaped below.
        unsafe { libc::kill(-(child.id() as libc::pid_t), libc::SIGKILL) };
        let status = child.wait().ok()?;
        by_itself.then_some(status)
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
            return Err(ControlStop::crash(format!("plugin {} is no longer running", self.name)));
        }
        let st = self.exchange(s, seq)?;
        let cmd = self.command;
        self.status.take("exoleg_step", st, || message_text(&cmd.message))?;
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
    /// BYE (the child destroys its instance and exits), then the child reaped: its process
    /// group killed (what the plugin forked), the child with it if it has not ended within a
    /// second.
    fn drop(&mut self) {
        if self.child.is_some() {
            let _ = self.sock.set_write_timeout(Some(Duration::from_millis(100)));
            let bye = Message::Bye { status: 0, message: String::new() };
            wire::encode(&Header { kind: MsgType::Bye, seq: 0, sim_time_ns: 0 }, &bye, &mut self.out);
            let _ = self.sock.write(&self.out);
            self.end_child(Duration::from_secs(1));
        }
    }
}
