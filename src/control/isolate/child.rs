//! The child's side of an isolated plugin (`exoleg plugin-host --fd N --library PATH`, run by
//! [`super::IsolatedPlugin`], never by hand): load the library, say HELLO on descriptor N,
//! create the instance from the SETUP, then answer every READINGS with the plugin's COMMAND
//! until BYE or the socket's end. A crash here is the point: the run sees the socket end and
//! names the signal.

use crate::control::plugin::{create_instance, ExolegCommand, PluginLibrary, STATUS_OK, STATUS_WARNING};
use crate::control::wire::{self, Header, Message, MsgType};
use std::io::{Read, Write};
use std::os::fd::FromRawFd;
use std::os::unix::net::UnixStream;
use std::path::Path;

/// Exit status of a host that could not do its job (a bad library, a broken peer).
const EXIT_HOST_FAILED: i32 = 2;

/// Serve the plugin at `library` on descriptor `fd`, its address space limited to `memory_mb`
/// MiB beyond what this process holds when it starts (`controller.plugin.memory_mb`). Returns
/// the process exit status.
pub fn serve(fd: i32, library: &Path, memory_mb: Option<u64>) -> i32 {
    crate::control::plugin::exit_guard::stand_aside();
    if fd < 3 {
        eprintln!("error: plugin-host: --fd {fd} is not a socket the run gave");
        return EXIT_HOST_FAILED;
    }
    // A SIGSEGV or SIGBUS the plugin raises itself (`raise()`, as firmware fault handlers do)
    // kills this process at once: the Rust runtime's own handler (for stack overflows) would
    // return from the first one and let the plugin go on.
    for sig in [libc::SIGSEGV, libc::SIGBUS] {
        // SAFETY: restoring a signal's default disposition.
        unsafe { libc::signal(sig, libc::SIG_DFL) };
    }
    if let Some(mb) = memory_mb {
        if let Err(e) = limit_memory(mb) {
            eprintln!("error: plugin-host: cannot limit the memory to {mb} MiB: {e}");
            return EXIT_HOST_FAILED;
        }
    }
    // SAFETY: the descriptor was made for this process by the run that started it (the only
    // caller), and nothing else here owns it.
    let mut sock = unsafe { UnixStream::from_raw_fd(fd) };
    let lib = match PluginLibrary::load(library) {
        Ok(l) => l,
        Err(e) => {
            let _ = send(&mut sock, 0, &Message::Ready { status: 2, message: e.clone() }, MsgType::Ready);
            eprintln!("error: plugin-host: {e}");
            return EXIT_HOST_FAILED;
        }
    };
    match session(&mut sock, &lib) {
        Ok(()) => 0,
        Err(e) => {
            eprintln!("error: plugin-host: {e}");
            EXIT_HOST_FAILED
        }
    }
}

/// `RLIMIT_AS` at this process's address space now plus `mb` MiB: the plugin's library and
/// allocations get `mb`.
fn limit_memory(mb: u64) -> std::io::Result<()> {
    let statm = std::fs::read_to_string("/proc/self/statm")?;
    let pages: u64 = statm.split_whitespace().next().and_then(|p| p.parse().ok()).unwrap_or(0);
    // SAFETY: sysconf has no preconditions.
    let page = unsafe { libc::sysconf(libc::_SC_PAGESIZE) }.max(4096) as u64;
    let bytes = pages.saturating_mul(page).saturating_add(mb.saturating_mul(1 << 20));
    let lim = libc::rlimit { rlim_cur: bytes as libc::rlim_t, rlim_max: bytes as libc::rlim_t };
    // SAFETY: a valid rlimit for this process.
    if unsafe { libc::setrlimit(libc::RLIMIT_AS, &lim) } != 0 {
        return Err(std::io::Error::last_os_error());
    }
    Ok(())
}

fn send(sock: &mut UnixStream, seq: u64, m: &Message, kind: MsgType) -> Result<(), String> {
    let mut out = Vec::new();
    wire::encode(&Header { kind, seq, sim_time_ns: 0 }, m, &mut out);
    sock.write_all(&out).map_err(|e| format!("cannot send: {e}"))
}

/// The next message; None at the socket's end.
fn receive(sock: &mut UnixStream, buf: &mut [u8]) -> Result<Option<(Header, Message)>, String> {
    let spin = std::time::Duration::from_secs_f64(super::SPIN_S);
    let mut got = super::receive_spinning(sock, buf, spin).unwrap_or_else(|| sock.read(buf));
    // A stop and continue of this process (Ctrl-Z, a debugger) is no end of the run.
    while matches!(&got, Err(e) if e.kind() == std::io::ErrorKind::Interrupted) {
        got = sock.read(buf);
    }
    match got {
        Ok(0) => Ok(None),
        Ok(n) => wire::decode(&buf[..n]).map(Some),
        Err(e) => Err(format!("cannot receive: {e}")),
    }
}

/// The handshake and the samples, the instance destroyed at the end.
fn session(sock: &mut UnixStream, lib: &PluginLibrary) -> Result<(), String> {
    let hello = Message::Hello { abi_version: wire::abi_version(), channel_hash: wire::channel_hash() };
    send(sock, 0, &hello, MsgType::Hello)?;
    let mut buf = vec![0u8; wire::MAX_DATAGRAM + 1];
    let setup = match receive(sock, &mut buf)? {
        Some((_, Message::Setup(s))) => s,
        None => return Ok(()),
        Some((h, _)) => return Err(format!("expected SETUP, got {:?}", h.kind)),
    };
    let handle = match create_instance(lib, &setup) {
        Ok(h) => h,
        Err(e) => return send(sock, 0, &Message::Ready { status: 2, message: e }, MsgType::Ready),
    };
    send(sock, 0, &Message::Ready { status: 0, message: String::new() }, MsgType::Ready)?;
    let r = samples(sock, lib, handle, &mut buf);
    lib.destroy_raw(handle);
    r
}

/// Answer READINGS with COMMAND until BYE or the end. At the first sample `exoleg_reset` has
/// its own COMMAND (`call` = reset, whatever its status) before the step's, so the run names
/// the call that hangs; a reset that warns still steps, one that stops does not.
fn samples(
    sock: &mut UnixStream,
    lib: &PluginLibrary,
    handle: *mut std::ffi::c_void,
    buf: &mut [u8],
) -> Result<(), String> {
    let mut reset = false;
    let mut out = Vec::with_capacity(wire::HEADER_LEN + wire::COMMAND_LEN);
    let mut reply = |sock: &mut UnixStream, h: &Header, status, call, t0: std::time::Instant, command| {
        let compute_ns = t0.elapsed().as_nanos() as u64;
        let m = Message::Command { status, call, compute_ns, command: Box::new(command) };
        wire::encode(&Header { kind: MsgType::Command, seq: h.seq, sim_time_ns: h.sim_time_ns }, &m, &mut out);
        sock.write_all(&out).map_err(|e| format!("cannot send: {e}"))
    };
    loop {
        let (h, r) = match receive(sock, buf)? {
            Some((h, Message::Readings(r))) => (h, r),
            Some((_, Message::Bye { .. })) | None => return Ok(()),
            Some((h, _)) => return Err(format!("expected READINGS, got {:?}", h.kind)),
        };
        if !reset {
            reset = true;
            let t0 = std::time::Instant::now();
            let status = lib.reset_raw(handle);
            reply(sock, &h, status, wire::CALL_RESET, t0, ExolegCommand::default())?;
            if status != STATUS_OK && status != STATUS_WARNING {
                continue;
            }
        }
        let mut command = ExolegCommand::default();
        let t0 = std::time::Instant::now();
        let status = lib.step_raw(handle, &r, &mut command);
        reply(sock, &h, status, wire::CALL_STEP, t0, command)?;
    }
}
