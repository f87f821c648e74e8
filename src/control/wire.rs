//! The wire protocol of a controller outside exoleg's process: one protocol, two transports.
//! An isolated plugin (`controller.plugin.isolate = true`, [`super::isolate`]) speaks it over a
//! Unix `SOCK_SEQPACKET` socket pair with its host process; a hardware-in-the-loop peer
//! (`exoleg hil`, `crate::hil`) over UDP. Every message is one datagram: a 24-byte header and a
//! payload, little-endian (the README's byte table; `include/exoleg_hil.h` is the C side).
//!
//! ```text
//! header   0 magic u32 = 0x4C4F5845 ("EXOL")   4 version u16 = 1   6 type u16
//!          8 seq u64 (the sample index; 0 in the handshake)   16 sim time u64 (ns)
//! peer  -> plant  HELLO     abi_version u32, reserved u32, channel_hash u64
//! plant -> peer   SETUP     abi_version u32, n_params u32, channel_hash u64, sample_period_s,
//!                           valve_command_limit, n1, n2, n3, tau_s, k_s (f64), seed u64, then
//!                           n_params x {name_len u16, name bytes (UTF-8), value f64}
//! peer  -> plant  READY     status i32 (0 created, 2 refused), reserved u32, message [160]
//! plant -> peer   READINGS  the ABI's ExolegReadings (its bytes, `size` first)
//! peer  -> plant  COMMAND   status i32, call u32 (0 step, 1 reset: its own COMMAND before the
//!                           first step's, or instead of it when not ok), compute_ns u64, the
//!                           ABI's ExolegCommand
//! plant -> peer   BYE       status i32, reserved u32, message [160] (the run is over)
//! plant -> peer   REFUSE    status i32, reserved u32, message [160] (the HELLO is refused)
//! ```
//! A COMMAND answers the READINGS of the same `seq`; a peer that gets the same READINGS twice
//! (a resend) answers with the same COMMAND without stepping again. Decoding never panics:
//! anything short, long, of another magic, version or type is an error naming what is wrong.

pub use super::plugin::InstanceSetup as Setup;
use super::plugin::{ExolegCommand, ExolegReadings, ABI_MAJOR, ABI_MINOR, MESSAGE_LEN};

const _: () = assert!(HEADER_LEN == super::plugin::WIRE_HEADER_LEN);

#[cfg(target_endian = "big")]
compile_error!("the wire protocol copies the ABI structs as they are in memory: little-endian hosts only");

/// `"EXOL"` read as a little-endian u32.
pub const MAGIC: u32 = 0x4C4F_5845;
/// The protocol's version (the header's).
pub const VERSION: u16 = 1;
/// Bytes of the header.
pub const HEADER_LEN: usize = 24;
pub use super::plugin::{MAX_DATAGRAM, MAX_NAME_LEN, SETUP_FIXED_LEN};

/// Message types (the header's `type`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u16)]
pub enum MsgType {
    /// Peer -> plant: who it is.
    Hello = 1,
    /// Plant -> peer: the run's figures and parameters.
    Setup = 2,
    /// Peer -> plant: the instance is created (or refused).
    Ready = 3,
    /// Plant -> peer: one sample's readings.
    Readings = 4,
    /// Peer -> plant: one sample's command.
    Command = 5,
    /// Plant -> peer: the run is over.
    Bye = 6,
    /// Plant -> peer: the HELLO is refused.
    Refuse = 7,
}

impl MsgType {
    fn from_u16(v: u16) -> Option<Self> {
        Some(match v {
            1 => MsgType::Hello,
            2 => MsgType::Setup,
            3 => MsgType::Ready,
            4 => MsgType::Readings,
            5 => MsgType::Command,
            6 => MsgType::Bye,
            7 => MsgType::Refuse,
            _ => return None,
        })
    }
}

/// The header of every message.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Header {
    /// What follows.
    pub kind: MsgType,
    /// Sample index (0 in the handshake).
    pub seq: u64,
    /// Simulated time of the sample (ns).
    pub sim_time_ns: u64,
}

/// The ABI version as the wire carries it, `(major << 16) | minor`.
pub const fn abi_version() -> u32 {
    (ABI_MAJOR << 16) | ABI_MINOR
}

/// FNV-1a (64 bit) of the readings' names in order, joined by `,`: the channel table both
/// sides must agree on (`EXOLEG_HIL_CHANNELS` in `include/exoleg_hil.h`).
pub fn channel_hash() -> u64 {
    fnv1a(channel_table().as_bytes())
}

/// The channel table: the readings' names ([`super::READINGS`]) in order, joined by `,`.
pub fn channel_table() -> String {
    super::READINGS.iter().map(|r| r.name).collect::<Vec<_>>().join(",")
}

/// FNV-1a, 64 bit.
pub fn fnv1a(bytes: &[u8]) -> u64 {
    let mut h: u64 = 0xcbf2_9ce4_8422_2325;
    for b in bytes {
        h ^= u64::from(*b);
        h = h.wrapping_mul(0x0100_0000_01b3);
    }
    h
}

/// A decoded message.
#[derive(Debug, Clone)]
pub enum Message {
    /// Peer -> plant: its ABI version and channel hash.
    Hello {
        /// `(major << 16) | minor`.
        abi_version: u32,
        /// [`channel_hash`] as the peer computes it.
        channel_hash: u64,
    },
    /// Plant -> peer.
    Setup(Setup),
    /// Peer -> plant: the instance exists (status 0) or not (2, with the message).
    Ready {
        /// 0 or 2.
        status: i32,
        /// Why not.
        message: String,
    },
    /// One sample's readings.
    Readings(Box<ExolegReadings>),
    /// One sample's command with the peer's status and its step's compute time (ns; 0 unknown).
    Command {
        /// The plugin's status for the call.
        status: i32,
        /// The call the status is from: [`CALL_STEP`] or [`CALL_RESET`] (the first sample's
        /// `exoleg_reset`: the isolated plugin's host sends its status in a COMMAND of its own
        /// before the step's; a peer may send it only when it is not ok).
        call: u32,
        /// Wall time of the step call as the peer measured it (ns).
        compute_ns: u64,
        /// The command.
        command: Box<ExolegCommand>,
    },
    /// Plant -> peer: the end (status 0 completed, else failed; the message says why).
    Bye {
        /// 0 completed.
        status: i32,
        /// Why not.
        message: String,
    },
    /// Plant -> peer: refused (the message says why).
    Refuse {
        /// Why.
        message: String,
    },
}

/// [`Message::Command`]'s `call`: the status is `exoleg_step`'s.
pub const CALL_STEP: u32 = 0;
/// [`Message::Command`]'s `call`: the status is `exoleg_reset`'s (a stop or an unknown status:
/// no step follows; ok or a warning: the step's COMMAND follows).
pub const CALL_RESET: u32 = 1;

/// Bytes of a READINGS payload.
pub const READINGS_LEN: usize = std::mem::size_of::<ExolegReadings>();
/// Bytes of a COMMAND payload.
pub const COMMAND_LEN: usize = 16 + std::mem::size_of::<ExolegCommand>();

/// Encode a message with its header into `out` (cleared first).
pub fn encode(h: &Header, m: &Message, out: &mut Vec<u8>) {
    out.clear();
    out.extend_from_slice(&MAGIC.to_le_bytes());
    out.extend_from_slice(&VERSION.to_le_bytes());
    out.extend_from_slice(&(h.kind as u16).to_le_bytes());
    out.extend_from_slice(&h.seq.to_le_bytes());
    out.extend_from_slice(&h.sim_time_ns.to_le_bytes());
    match m {
        Message::Hello { abi_version, channel_hash } => {
            out.extend_from_slice(&abi_version.to_le_bytes());
            out.extend_from_slice(&0u32.to_le_bytes());
            out.extend_from_slice(&channel_hash.to_le_bytes());
        }
        Message::Setup(s) => encode_setup(s, out),
        Message::Ready { status, message } | Message::Bye { status, message } => status_message(*status, message, out),
        Message::Refuse { message } => status_message(2, message, out),
        Message::Readings(r) => out.extend_from_slice(struct_bytes(&**r)),
        Message::Command { status, call, compute_ns, command } => {
            out.extend_from_slice(&status.to_le_bytes());
            out.extend_from_slice(&call.to_le_bytes());
            out.extend_from_slice(&compute_ns.to_le_bytes());
            out.extend_from_slice(struct_bytes(&**command));
        }
    }
}

fn encode_setup(s: &Setup, out: &mut Vec<u8>) {
    out.extend_from_slice(&abi_version().to_le_bytes());
    out.extend_from_slice(&(s.params.len() as u32).to_le_bytes());
    out.extend_from_slice(&channel_hash().to_le_bytes());
    for x in [s.sample_period_s, s.valve_command_limit].iter().chain(&s.nominal) {
        out.extend_from_slice(&x.to_le_bytes());
    }
    out.extend_from_slice(&s.seed.to_le_bytes());
    for (name, value) in &s.params {
        let n = &name.as_bytes()[..name.len().min(MAX_NAME_LEN)];
        out.extend_from_slice(&(n.len() as u16).to_le_bytes());
        out.extend_from_slice(n);
        out.extend_from_slice(&value.to_le_bytes());
    }
}

fn status_message(status: i32, message: &str, out: &mut Vec<u8>) {
    out.extend_from_slice(&status.to_le_bytes());
    out.extend_from_slice(&0u32.to_le_bytes());
    let mut buf = [0u8; MESSAGE_LEN];
    let b = message.as_bytes();
    let n = b.len().min(MESSAGE_LEN - 1);
    buf[..n].copy_from_slice(&b[..n]);
    out.extend_from_slice(&buf);
}

/// The bytes of a plain-data ABI struct (no padding, no pointers: [`ExolegReadings`],
/// [`ExolegCommand`]).
fn struct_bytes<T: PlainData>(x: &T) -> &[u8] {
    // SAFETY: `PlainData` types are `repr(C)` structs of integers, floats and byte arrays
    // without padding (the ABI layout test checks every offset), so every byte is initialised.
    unsafe { std::slice::from_raw_parts((x as *const T).cast::<u8>(), std::mem::size_of::<T>()) }
}

/// A plain-data ABI struct from exactly its size in bytes.
fn from_bytes<T: PlainData>(b: &[u8]) -> Option<T> {
    (b.len() == std::mem::size_of::<T>()).then(|| {
        // SAFETY: the length is the struct's; every bit pattern is a valid value of its fields
        // (integers, floats, C chars).
        unsafe { std::ptr::read_unaligned(b.as_ptr().cast::<T>()) }
    })
}

/// Structs of integers, floats and byte arrays without padding.
///
/// # Safety
/// Implement only for such structs.
unsafe trait PlainData: Copy {}
// SAFETY: see the trait; the layout test (tests/it/your_controller.rs) checks the offsets.
unsafe impl PlainData for ExolegReadings {}
// SAFETY: as above.
unsafe impl PlainData for ExolegCommand {}

/// A reader over a payload: every read checks the length.
struct Cursor<'a>(&'a [u8]);

impl Cursor<'_> {
    fn take(&mut self, n: usize, what: &str) -> Result<&[u8], String> {
        if self.0.len() < n {
            return Err(format!("truncated: {what} needs {n} more bytes, {} left", self.0.len()));
        }
        let (a, b) = self.0.split_at(n);
        self.0 = b;
        Ok(a)
    }
    fn u16(&mut self, what: &str) -> Result<u16, String> {
        Ok(u16::from_le_bytes(self.take(2, what)?.try_into().unwrap_or_default()))
    }
    fn u32(&mut self, what: &str) -> Result<u32, String> {
        Ok(u32::from_le_bytes(self.take(4, what)?.try_into().unwrap_or_default()))
    }
    fn u64(&mut self, what: &str) -> Result<u64, String> {
        Ok(u64::from_le_bytes(self.take(8, what)?.try_into().unwrap_or_default()))
    }
    fn f64(&mut self, what: &str) -> Result<f64, String> {
        Ok(f64::from_bits(self.u64(what)?))
    }
    fn done(&self, what: &str) -> Result<(), String> {
        match self.0.len() {
            0 => Ok(()),
            n => Err(format!("oversized: {n} bytes after the {what}")),
        }
    }
}

/// Decode the header of a datagram (magic, version and type checked).
pub fn decode_header(b: &[u8]) -> Result<Header, String> {
    if b.len() > MAX_DATAGRAM {
        return Err(format!("oversized: {} bytes (at most {MAX_DATAGRAM})", b.len()));
    }
    let mut c = Cursor(b);
    let magic = c.u32("the header")?;
    if magic != MAGIC {
        return Err(format!("wrong magic 0x{magic:08x} (an exoleg message starts with 0x{MAGIC:08x}, \"EXOL\")"));
    }
    let version = c.u16("the header")?;
    if version != VERSION {
        return Err(format!("protocol version {version}, this exoleg speaks {VERSION}"));
    }
    let t = c.u16("the header")?;
    let kind = MsgType::from_u16(t).ok_or_else(|| format!("unknown message type {t}"))?;
    let seq = c.u64("the header")?;
    let sim_time_ns = c.u64("the header")?;
    Ok(Header { kind, seq, sim_time_ns })
}

/// Decode a whole datagram. Errors say what is wrong (truncated, oversized, wrong magic, ...).
pub fn decode(b: &[u8]) -> Result<(Header, Message), String> {
    let h = decode_header(b)?;
    let mut c = Cursor(&b[HEADER_LEN..]);
    let m = match h.kind {
        MsgType::Hello => {
            let abi_version = c.u32("HELLO")?;
            c.u32("HELLO")?;
            let channel_hash = c.u64("HELLO")?;
            Message::Hello { abi_version, channel_hash }
        }
        MsgType::Setup => Message::Setup(decode_setup(&mut c)?),
        MsgType::Ready | MsgType::Bye | MsgType::Refuse => {
            let status = c.u32("the status")? as i32;
            c.u32("the status")?;
            let message = message_of(c.take(MESSAGE_LEN, "the message")?);
            match h.kind {
                MsgType::Ready => Message::Ready { status, message },
                MsgType::Bye => Message::Bye { status, message },
                _ => Message::Refuse { message },
            }
        }
        MsgType::Readings => {
            let r: ExolegReadings =
                from_bytes(c.take(READINGS_LEN, "READINGS")?).ok_or_else(|| "READINGS: bad size".to_string())?;
            if r.size as usize != READINGS_LEN {
                return Err(format!("READINGS: size field {} (the struct is {READINGS_LEN} bytes)", r.size));
            }
            Message::Readings(Box::new(r))
        }
        MsgType::Command => {
            let status = c.u32("COMMAND")? as i32;
            let call = c.u32("COMMAND")?;
            let compute_ns = c.u64("COMMAND")?;
            let command: ExolegCommand =
                from_bytes(c.take(COMMAND_LEN - 16, "COMMAND")?).ok_or_else(|| "COMMAND: bad size".to_string())?;
            Message::Command { status, call, compute_ns, command: Box::new(command) }
        }
    };
    c.done(&format!("{:?} payload", h.kind))?;
    Ok((h, m))
}

fn decode_setup(c: &mut Cursor) -> Result<Setup, String> {
    let _abi = c.u32("SETUP")?;
    let n = c.u32("SETUP")? as usize;
    if n > super::plugin::MAX_PARAMS {
        return Err(format!("SETUP: {n} parameters (at most {})", super::plugin::MAX_PARAMS));
    }
    let _hash = c.u64("SETUP")?;
    let sample_period_s = c.f64("SETUP")?;
    let valve_command_limit = c.f64("SETUP")?;
    let mut nominal = [0.0; 5];
    for x in &mut nominal {
        *x = c.f64("SETUP")?;
    }
    let seed = c.u64("SETUP")?;
    let mut params = Vec::with_capacity(n);
    for _ in 0..n {
        let len = c.u16("a parameter name")? as usize;
        let name = String::from_utf8_lossy(c.take(len, "a parameter name")?).into_owned();
        params.push((name, c.f64("a parameter value")?));
    }
    Ok(Setup { sample_period_s, valve_command_limit, nominal, seed, params })
}

/// A message buffer's text: up to the first NUL, invalid UTF-8 replaced, control characters
/// escaped.
fn message_of(b: &[u8]) -> String {
    let end = b.iter().position(|&x| x == 0).unwrap_or(b.len());
    super::plugin::escape_controls(String::from_utf8_lossy(&b[..end]).trim())
}

/// Simulated time (s) as the header's ns (saturating; negative or NaN is 0).
pub fn time_ns(t_s: f64) -> u64 {
    (t_s * 1e9).round().clamp(0.0, u64::MAX as f64) as u64
}

/// The fuzz target `wire`: decoding any bytes gives a message or an error, never a panic,
/// and a decoded message encodes back to the same bytes it came from.
pub fn fuzz_wire(bytes: &[u8]) -> Result<(), String> {
    let (h, m) = decode(bytes)?;
    let mut again = Vec::new();
    encode(&h, &m, &mut again);
    // The fixed-layout messages round-trip byte for byte (HELLO's reserved word is not kept).
    let exact = match m {
        Message::Readings(_) => true,
        Message::Hello { .. } => bytes[28..32] == [0; 4],
        _ => false,
    };
    if exact && again[..] != bytes[..] {
        return Err("a decoded message encodes to other bytes".into());
    }
    decode(&again).map(|_| ()).map_err(|e| format!("re-encoded message does not decode: {e}"))
}
