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

/// Serve the plugin at `library` on descriptor `fd`. Returns the process exit status.
pub fn serve(fd: i32, library: &Path) -> i32 {
    crate::control::plugin::exit_guard::stand_aside();
    if fd < 3 {
        eprintln!("error: plugin-host: --fd {fd} is not a socket the run gave");
        return EXIT_HOST_FAILED;
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

fn send(sock: &mut UnixStream, seq: u64, m: &Message, kind: MsgType) -> Result<(), String> {
    let mut out = Vec::new();
    wire::encode(&Header { kind, seq, sim_time_ns: 0 }, m, &mut out);
    sock.write_all(&out).map_err(|e| format!("cannot send: {e}"))
}

/// The next message; None at the socket's end.
fn receive(sock: &mut UnixStream, buf: &mut [u8]) -> Result<Option<(Header, Message)>, String> {
    let spin = std::time::Duration::from_secs_f64(super::SPIN_S);
    match super::receive_spinning(sock, buf, spin).unwrap_or_else(|| sock.read(buf)) {
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

/// Answer READINGS with COMMAND until BYE or the end.
fn samples(
    sock: &mut UnixStream,
    lib: &PluginLibrary,
    handle: *mut std::ffi::c_void,
    buf: &mut [u8],
) -> Result<(), String> {
    let mut reset = false;
    let mut out = Vec::with_capacity(wire::HEADER_LEN + wire::COMMAND_LEN);
    loop {
        let (h, r) = match receive(sock, buf)? {
            Some((h, Message::Readings(r))) => (h, r),
            Some((_, Message::Bye { .. })) | None => return Ok(()),
            Some((h, _)) => return Err(format!("expected READINGS, got {:?}", h.kind)),
        };
        let mut command = ExolegCommand::default();
        let (mut status, mut call) = (STATUS_OK, wire::CALL_STEP);
        if !reset {
            reset = true;
            status = lib.reset_raw(handle);
            call = wire::CALL_RESET;
        }
        let t0 = std::time::Instant::now();
        // A reset that warns still steps (its warning is not counted); one that stops does not.
        if status == STATUS_OK || status == STATUS_WARNING {
            status = lib.step_raw(handle, &r, &mut command);
            call = wire::CALL_STEP;
        }
        let compute_ns = t0.elapsed().as_nanos() as u64;
        let m = Message::Command { status, call, compute_ns, command: Box::new(command) };
        wire::encode(&Header { kind: MsgType::Command, seq: h.seq, sim_time_ns: h.sim_time_ns }, &m, &mut out);
        sock.write_all(&out).map_err(|e| format!("cannot send: {e}"))?;
    }
}
