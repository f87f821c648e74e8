//! Hardware in the loop over UDP (`exoleg hil`): the plant runs here, the controller is a peer
//! elsewhere (a board, another process, another machine) speaking the wire protocol
//! ([`crate::control::wire`], the README's byte table; `include/exoleg_hil.h` and
//! `examples/hil/exoleg_hil.c` are the C side, `exoleg.hil` the Python one). The peer is a
//! [`DiscreteController`] to the loop, like an in-process or isolated plugin.
//!
//! Two modes ([`Mode`]):
//! - **lockstep**: the plant waits for the COMMAND of every sample, however long it takes
//!   (READINGS resent every `resend_s`, each resend counted; the peer answers a resend with
//!   the same COMMAND without stepping again). The run equals the in-process plugin's bit for
//!   bit. A stall watchdog ends the run when no COMMAND comes for `stall_timeout_s`.
//! - **realtime**: the plant is paced at wall-clock time, one sample every sample period; a
//!   COMMAND that misses its sample's deadline (the next sample instant, at least half a period
//!   after the READINGS went out when the plant runs late) is counted, and the
//!   valve gets the [`OnMiss`] policy's command (the last one held, or zero). A COMMAND that
//!   comes later is counted late and not used; one that never comes is lost.
//!
//! Every datagram that does not decode is counted and ignored; a peer whose HELLO has another
//! ABI major, protocol version or channel table is refused and the run ends (exit 3).

pub mod link;

use crate::control::plugin::{message_text, output_of, ExolegCommand, InstanceSetup, StatusCount};
use crate::control::timing::TimingStats;
use crate::control::wire::{self, Header, Message, MsgType};
use crate::control::{ControlOutput, ControlStop, DiscreteController, SampleInput};
use link::{Link, Received};
use std::time::{Duration, Instant};

/// How the plant waits for the peer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Mode {
    /// Wait for every command (bit-identical to the in-process plugin).
    Lockstep,
    /// Paced at wall-clock time; late commands are missed.
    Realtime,
}

/// What the valve gets at a sample whose command missed its deadline (realtime).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum OnMiss {
    /// The last command is held.
    Hold,
    /// The valve command 0 (the valve centred: the cylinder's chambers closed).
    Zero,
}

/// A HIL run's link settings.
#[derive(Debug, Clone)]
pub struct HilOptions {
    /// ADDR:PORT to listen on (port 0: any; the bound address is printed).
    pub listen: String,
    /// Lockstep or realtime.
    pub mode: Mode,
    /// How long to wait for the peer's HELLO and READY (s).
    pub wait_s: f64,
    /// The longest time without a valid COMMAND before the run ends (s).
    pub stall_timeout_s: f64,
    /// Lockstep: READINGS are sent again after this long without an answer (s).
    pub resend_s: f64,
    /// Realtime: the command of a missed sample.
    pub on_miss: OnMiss,
}

/// The peer as the loop's controller.
pub struct HilController {
    link: Link,
    opts: HilOptions,
    log_names: Vec<String>,
    command: ExolegCommand,
    status: StatusCount,
    compute_s: Vec<f64>,
    round_trip_s: Vec<f64>,
    jitter_s: Vec<f64>,
    /// Realtime: when each sample's READINGS went out, and whether its COMMAND came.
    sent: Vec<(Instant, bool)>,
    /// Realtime: the wall-clock instant of sample 0.
    start: Option<Instant>,
    last_valid: Instant,
    missed: usize,
    plant_overruns: usize,
}

impl HilController {
    /// Listen, wait for the peer's HELLO and READY: the controller of a run (errors say what
    /// went wrong: nobody came, a refused HELLO, a refused instance).
    pub fn connect(setup: &InstanceSetup, log_names: Vec<String>, opts: HilOptions) -> Result<Self, String> {
        let link = Link::bind(&opts.listen)?;
        Self::on_link(link, setup, log_names, opts)
    }

    /// Bind first (to print the address), then [`Self::on_link`].
    pub fn bind(listen: &str) -> Result<Link, String> {
        Link::bind(listen)
    }

    /// The handshake on a bound link.
    pub fn on_link(
        mut link: Link,
        setup: &InstanceSetup,
        log_names: Vec<String>,
        opts: HilOptions,
    ) -> Result<Self, String> {
        link.handshake(setup, Duration::from_secs_f64(opts.wait_s))?;
        let name = format!("HIL peer {}", link.peer.map_or("?".into(), |p| p.to_string()));
        Ok(Self {
            link,
            opts,
            log_names,
            command: ExolegCommand::default(),
            status: StatusCount::new(name),
            compute_s: Vec::new(),
            round_trip_s: Vec::new(),
            jitter_s: Vec::new(),
            sent: Vec::new(),
            start: None,
            last_valid: Instant::now(),
            missed: 0,
            plant_overruns: 0,
        })
    }

    fn stop(&self, seq: u64, t_s: f64, why: String) -> ControlStop {
        ControlStop { message: format!("{} at sample {seq} (t = {t_s:.6} s): {why}", self.status.name) }
    }

    fn send_readings(&mut self, s: &SampleInput, seq: u64) -> Result<(), ControlStop> {
        let r = crate::control::plugin::readings_of(s);
        let h = Header { kind: MsgType::Readings, seq, sim_time_ns: wire::time_ns(s.t_s) };
        self.link.send(&h, &Message::Readings(Box::new(r))).map_err(|e| self.stop(seq, s.t_s, e))
    }

    /// Take a COMMAND for `seq` (its status and figures); the output.
    fn accept(
        &mut self,
        status: i32,
        call: u32,
        compute_ns: u64,
        command: ExolegCommand,
    ) -> Result<ControlOutput, ControlStop> {
        self.command = command;
        self.compute_s.push(compute_ns as f64 * 1e-9);
        self.last_valid = Instant::now();
        let call = if call == wire::CALL_RESET { "exoleg_reset" } else { "exoleg_step" };
        self.status.take(call, status, || message_text(&command.message))?;
        output_of(&self.status.name, &self.command, status)
    }

    /// Lockstep: send, wait (resending) for this sample's COMMAND.
    fn lockstep(&mut self, s: &SampleInput, seq: u64) -> Result<ControlOutput, ControlStop> {
        let t0 = Instant::now();
        self.send_readings(s, seq)?;
        let resend = Duration::from_secs_f64(self.opts.resend_s);
        loop {
            let got = self.link.receive(resend).map_err(|e| self.stop(seq, s.t_s, e))?.0;
            match got {
                Received::Message(h, Message::Command { status, call, compute_ns, command }) if h.seq == seq => {
                    self.round_trip_s.push(t0.elapsed().as_secs_f64());
                    return self.accept(status, call, compute_ns, *command);
                }
                Received::Message(h, Message::Command { .. }) if h.seq < seq => self.link.counts.duplicated += 1,
                Received::Message(_, Message::Command { .. }) => self.link.counts.out_of_order += 1,
                Received::Message(..) => self.link.counts.unexpected += 1,
                Received::Timeout => {
                    if self.last_valid.elapsed().as_secs_f64() > self.opts.stall_timeout_s {
                        return Err(self.stalled(seq, s.t_s));
                    }
                    self.link.counts.resent += 1;
                    self.send_readings(s, seq)?;
                }
            }
        }
    }

    fn stalled(&self, seq: u64, t_s: f64) -> ControlStop {
        let c = &self.link.counts;
        let junk = c.last_malformed.as_ref().map_or(String::new(), |e| format!(", the last malformed: {e}"));
        self.stop(
            seq,
            t_s,
            format!(
                "no COMMAND for {} s (the stall watchdog, --stall-timeout-s): {} resends, {} malformed datagrams{junk}",
                self.opts.stall_timeout_s, c.resent, c.malformed
            ),
        )
    }

    /// Realtime: at the sample's wall-clock instant send; wait until the next instant for its
    /// COMMAND; else the miss policy.
    fn realtime(&mut self, s: &SampleInput, seq: u64) -> Result<ControlOutput, ControlStop> {
        let period = Duration::from_secs_f64(s.period_s);
        let start = *self.start.get_or_insert_with(|| Instant::now() - period.mul_f64(seq as f64));
        let scheduled = start + period.mul_f64(seq as f64);
        sleep_until(scheduled);
        let late_by = Instant::now().saturating_duration_since(scheduled);
        self.jitter_s.push(late_by.as_secs_f64());
        self.plant_overruns += usize::from(late_by > period);
        let i = seq as usize;
        if self.sent.len() <= i {
            self.sent.resize(i + 1, (Instant::now(), true));
        }
        let sent_at = Instant::now();
        self.sent[i] = (sent_at, false);
        self.send_readings(s, seq)?;
        // The next sample instant; when the plant itself is late (an overrun), at least half a
        // period after the READINGS went out.
        let deadline = (scheduled + period).max(sent_at + period / 2);
        loop {
            let left = deadline.saturating_duration_since(Instant::now());
            let got = self.link.receive(left).map_err(|e| self.stop(seq, s.t_s, e))?.0;
            match got {
                Received::Message(h, Message::Command { status, call, compute_ns, command }) => {
                    let k = h.seq as usize;
                    match self.sent.get_mut(k) {
                        Some((_, true)) => self.link.counts.duplicated += 1,
                        Some((at, answered)) => {
                            *answered = true;
                            self.round_trip_s.push(at.elapsed().as_secs_f64());
                            if k == i {
                                return self.accept(status, call, compute_ns, *command);
                            }
                            self.link.counts.late += 1;
                        }
                        None => self.link.counts.out_of_order += 1,
                    }
                }
                Received::Message(..) => self.link.counts.unexpected += 1,
                Received::Timeout => return self.missed(seq, s.t_s),
            }
        }
    }

    /// A sample whose command missed its deadline: counted, the policy's command.
    fn missed(&mut self, seq: u64, t_s: f64) -> Result<ControlOutput, ControlStop> {
        self.missed += 1;
        if self.last_valid.elapsed().as_secs_f64() > self.opts.stall_timeout_s {
            return Err(self.stalled(seq, t_s));
        }
        match self.opts.on_miss {
            OnMiss::Hold => output_of(&self.status.name, &self.command, 0),
            OnMiss::Zero => Ok(ControlOutput::default()),
        }
    }

    /// Samples whose COMMAND never came (realtime).
    fn lost(&self) -> usize {
        self.sent.iter().filter(|(_, answered)| !answered).count()
    }
}

/// Sleep until `t`: the kernel's sleep while far, a spin for the last 200 us.
fn sleep_until(t: Instant) {
    loop {
        let now = Instant::now();
        if now >= t {
            return;
        }
        let left = t - now;
        if left > Duration::from_micros(300) {
            std::thread::sleep(left - Duration::from_micros(200));
        } else {
            std::hint::spin_loop();
        }
    }
}

impl DiscreteController for HilController {
    fn kind(&self) -> &str {
        "hil"
    }

    fn update(&mut self, s: &SampleInput) -> Result<ControlOutput, ControlStop> {
        let seq = if s.period_s > 0.0 { (s.t_s / s.period_s).round() as u64 } else { 0 };
        match self.opts.mode {
            Mode::Lockstep => self.lockstep(s, seq),
            Mode::Realtime => self.realtime(s, seq),
        }
    }

    fn log_names(&self) -> Vec<String> {
        self.log_names.clone()
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
        let c = &self.link.counts;
        let realtime = self.opts.mode == Mode::Realtime;
        Some(serde_json::json!({
            "transport": "udp",
            "mode": if realtime { "realtime" } else { "lockstep" },
            "peer": self.link.peer.map(|p| p.to_string()),
            "round_trip": TimingStats::of(&self.round_trip_s),
            "lost": if realtime { self.lost() } else { 0 },
            "late": c.late,
            "duplicated": c.duplicated,
            "out_of_order": c.out_of_order,
            "malformed": c.malformed,
            "unexpected": c.unexpected,
            "resent": c.resent,
            "missed_deadlines": self.missed,
            "on_miss": if self.opts.on_miss == OnMiss::Hold { "hold" } else { "zero" },
            "pacing_jitter": TimingStats::of(&self.jitter_s),
            "plant_overruns": self.plant_overruns,
        }))
    }
}

impl Drop for HilController {
    /// BYE: the peer destroys its instance.
    fn drop(&mut self) {
        let bye = Message::Bye { status: 0, message: "the run is over".into() };
        let _ = self.link.send(&Header { kind: MsgType::Bye, seq: 0, sim_time_ns: 0 }, &bye);
    }
}
