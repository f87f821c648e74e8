//! The UDP side of a HIL run: the socket, the handshake (HELLO checked, SETUP sent, READY
//! awaited), every datagram sorted (the expected COMMAND, a late or duplicated one, one from
//! the future, a malformed one) and counted.

use crate::control::wire::{self, Header, Message, MsgType, Setup};
use std::io::ErrorKind;
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};

/// What the link counted (the `controller_link` figures of `summary.json`).
#[derive(Debug, Clone, Default)]
pub struct Counts {
    /// Datagrams that did not decode (wrong magic, truncated, oversized, unknown type).
    pub malformed: usize,
    /// The last decode error, for messages.
    pub last_malformed: Option<String>,
    /// COMMANDs for a sample already answered (a resend's answer, a duplicate).
    pub duplicated: usize,
    /// COMMANDs for an earlier sample that came after their deadline (realtime).
    pub late: usize,
    /// COMMANDs for a sample not asked yet (from the future).
    pub out_of_order: usize,
    /// Datagrams of another type than the run expects now.
    pub unexpected: usize,
    /// READINGS sent again because no answer came (lockstep).
    pub resent: usize,
    /// Datagrams from anyone but the peer (or, before the handshake, from an address
    /// `--allow-from` does not allow): dropped unread.
    pub strangers: usize,
    /// Pauses of this process (a stop and continue) the link waited through.
    pub pauses: usize,
}

/// One datagram as the run sees it.
pub enum Received {
    /// A decoded message.
    Message(Header, Message),
    /// Nothing within the time given.
    Timeout,
}

/// The socket and its peer.
pub struct Link {
    sock: UdpSocket,
    /// The peer (after its HELLO).
    pub peer: Option<SocketAddr>,
    /// Who may say HELLO (`--allow-from`; empty: anyone).
    allow: Vec<Allowed>,
    buf: Vec<u8>,
    out: Vec<u8>,
    /// What was counted.
    pub counts: Counts,
    /// The last wait spanned a pause of this process (taken by [`Self::take_pause`]).
    paused: bool,
}

/// An address `--allow-from` lets say HELLO: an IP (any port) or an IP and port.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Allowed {
    /// Any port of this address.
    Ip(std::net::IpAddr),
    /// This address and port.
    Addr(SocketAddr),
}

impl Allowed {
    /// Parse `ADDR` or `ADDR:PORT` (`[v6]:PORT`).
    pub fn parse(s: &str) -> Result<Self, String> {
        if let Ok(a) = s.parse::<SocketAddr>() {
            return Ok(Allowed::Addr(a));
        }
        s.parse::<std::net::IpAddr>()
            .map(Allowed::Ip)
            .map_err(|_| format!("`{s}`: give an IP address (any port) or ADDR:PORT"))
    }

    fn admits(&self, from: SocketAddr) -> bool {
        match self {
            Allowed::Ip(ip) => from.ip() == *ip,
            Allowed::Addr(a) => from == *a,
        }
    }
}

/// Why the link failed.
pub type LinkError = String;

impl Link {
    /// Bind `listen` (ADDR:PORT); only `allow` may say HELLO (empty: anyone).
    pub fn bind(listen: &str, allow: Vec<Allowed>) -> Result<Self, LinkError> {
        let sock = UdpSocket::bind(listen).map_err(|e| format!("cannot listen on {listen}: {e}"))?;
        Ok(Self {
            sock,
            peer: None,
            allow,
            buf: vec![0; wire::MAX_DATAGRAM + 1],
            out: Vec::with_capacity(wire::HEADER_LEN + wire::READINGS_LEN),
            counts: Counts::default(),
            paused: false,
        })
    }

    /// Whether a wait since the last call spanned a pause of this process (a stop and
    /// continue): the callers' timers restart.
    pub fn take_pause(&mut self) -> bool {
        std::mem::take(&mut self.paused)
    }

    /// Whether a datagram from `from` is the run's: the peer's, or before the handshake one
    /// `--allow-from` allows.
    fn admits(&self, from: SocketAddr) -> bool {
        match self.peer {
            Some(p) => from == p,
            None => self.allow.is_empty() || self.allow.iter().any(|a| a.admits(from)),
        }
    }

    /// The address bound (the port chosen when `listen` asked for port 0).
    pub fn local_addr(&self) -> Option<SocketAddr> {
        self.sock.local_addr().ok()
    }

    /// Send `m` to the peer.
    pub fn send(&mut self, h: &Header, m: &Message) -> Result<(), LinkError> {
        wire::encode(h, m, &mut self.out);
        let r = match self.peer {
            Some(_) => self.sock.send(&self.out),
            None => return Err("no peer yet".into()),
        };
        r.map(|_| ()).map_err(|e| self.gone(e))
    }

    fn gone(&self, e: std::io::Error) -> LinkError {
        let peer = self.peer.map_or("?".to_string(), |p| p.to_string());
        match e.kind() {
            ErrorKind::ConnectionRefused => {
                format!("the peer at {peer} is gone (its port refuses: connection refused)")
            }
            _ => format!("the link to {peer} failed: {e}"),
        }
    }

    /// The next datagram from the peer that decodes, waiting up to `limit` (at least one read,
    /// however little is left); malformed ones are counted and skipped, and every datagram
    /// not from the peer (before the handshake: not from an allowed address) is dropped
    /// unread and counted, whenever it came (one queued before the handshake too). A wait
    /// that spans a pause of this process is retried and remembered ([`Self::take_pause`]).
    pub fn receive(&mut self, limit: Duration) -> Result<(Received, Option<SocketAddr>), LinkError> {
        let t0 = Instant::now();
        let mut first = true;
        loop {
            let left = limit.saturating_sub(t0.elapsed());
            if left.is_zero() && !first {
                return Ok((Received::Timeout, None));
            }
            first = false;
            let asked = left.max(Duration::from_micros(10));
            self.sock.set_read_timeout(Some(asked)).map_err(|e| self.gone(e))?;
            let started = Instant::now();
            let got = self.sock.recv_from(&mut self.buf);
            let interrupted = matches!(&got, Err(e) if e.kind() == ErrorKind::Interrupted);
            if crate::control::wait::was_paused(started, asked, interrupted) {
                self.paused = true;
                self.counts.pauses += 1;
            }
            let (n, from) = match got {
                Ok(x) => x,
                Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut | ErrorKind::Interrupted) => {
                    continue
                }
                Err(e) => return Err(self.gone(e)),
            };
            if !self.admits(from) {
                self.counts.strangers += 1;
                continue;
            }
            match wire::decode(&self.buf[..n]) {
                Ok((h, m)) => return Ok((Received::Message(h, m), Some(from))),
                Err(e) => {
                    // A peer of another protocol version is refused, not ignored.
                    if self.peer.is_none() && e.starts_with("protocol version") {
                        self.refuse(from, &e);
                        return Err(format!("refused the peer at {from}: {e}"));
                    }
                    self.counts.malformed += 1;
                    self.counts.last_malformed = Some(e);
                }
            }
        }
    }

    /// Tell `to` why it is refused (best effort).
    fn refuse(&mut self, to: SocketAddr, why: &str) {
        let mut out = Vec::new();
        let h = Header { kind: MsgType::Refuse, seq: 0, sim_time_ns: 0 };
        wire::encode(&h, &Message::Refuse { message: why.to_string() }, &mut out);
        let _ = self.sock.send_to(&out, to);
    }

    /// Wait up to `wait` for a HELLO of this ABI and channel table, then SETUP it and wait up to
    /// `wait` for READY. A HELLO of another ABI major or channel table is refused (the peer is
    /// told why) and ends the run.
    pub fn handshake(&mut self, setup: &Setup, wait: Duration) -> Result<(), LinkError> {
        let mut deadline = crate::control::wait::Deadline::new(wait);
        let peer = loop {
            let got = self.receive(deadline.left())?;
            if self.take_pause() {
                deadline.restart();
            }
            match got {
                (Received::Timeout, _) if deadline.passed() => return Err(self.no_peer(wait)),
                (Received::Timeout, _) => {}
                (Received::Message(_, Message::Hello { abi_version, channel_hash }), Some(from)) => {
                    self.check_hello(from, abi_version, channel_hash)?;
                    break from;
                }
                _ => self.counts.unexpected += 1,
            }
        };
        self.sock.connect(peer).map_err(|e| format!("cannot connect to {peer}: {e}"))?;
        self.peer = Some(peer);
        let h = Header { kind: MsgType::Setup, seq: 0, sim_time_ns: 0 };
        self.send(&h, &Message::Setup(setup.clone()))?;
        loop {
            let got = self.receive(deadline.left())?.0;
            if self.take_pause() {
                deadline.restart();
            }
            match got {
                Received::Timeout if !deadline.passed() => {}
                Received::Timeout => {
                    return Err(format!("the peer at {peer} sent no READY in {} s", wait.as_secs_f64()))
                }
                Received::Message(_, Message::Ready { status: 0, .. }) => return Ok(()),
                Received::Message(_, Message::Ready { message, .. }) => {
                    return Err(format!("the peer at {peer} could not create its instance: {message}"))
                }
                // Its HELLO again (our SETUP lost): SETUP again.
                Received::Message(_, Message::Hello { .. }) => self.send(&h, &Message::Setup(setup.clone()))?,
                Received::Message(..) => self.counts.unexpected += 1,
            }
        }
    }

    fn check_hello(&mut self, from: SocketAddr, abi_version: u32, channel_hash: u64) -> Result<(), LinkError> {
        let why = if abi_version >> 16 != wire::abi_version() >> 16 {
            Some(format!(
                "ABI version {}.{}, this exoleg speaks {}.{} (the major versions must match)",
                abi_version >> 16,
                abi_version & 0xffff,
                wire::abi_version() >> 16,
                wire::abi_version() & 0xffff
            ))
        } else if channel_hash != wire::channel_hash() {
            Some(format!(
                "channel table hash 0x{channel_hash:016x}, this exoleg's is 0x{:016x} (the readings' names and order differ: rebuild against include/exoleg_hil.h)",
                wire::channel_hash()
            ))
        } else {
            None
        };
        match why {
            Some(w) => {
                self.refuse(from, &w);
                Err(format!("refused the peer at {from}: {w}"))
            }
            None => Ok(()),
        }
    }

    fn no_peer(&self, wait: Duration) -> LinkError {
        let junk = match (&self.counts.last_malformed, self.counts.malformed) {
            (Some(e), n) => format!(" ({n} malformed datagrams ignored, the last: {e})"),
            (None, _) => String::new(),
        };
        let at = self.local_addr().map_or("?".into(), |a| a.to_string());
        format!("no controller peer said HELLO on {at} within {} s{junk}", wait.as_secs_f64())
    }
}
