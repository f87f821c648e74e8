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
//!
//! The protocol is unauthenticated: whoever reaches the port first with a HELLO (of an
//! address `--allow-from` allows) is the peer; from then on every datagram from anyone else is
//! dropped unread and counted (`strangers`), one queued before the handshake too.

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
    /// Who may say HELLO (`--allow-from`; empty: anyone who reaches the port).
    pub allow_from: Vec<link::Allowed>,
}

/// `--wait-s`' and `--stall-timeout-s`' range (s): up to a day.
pub const WAIT_RANGE_S: (f64, f64) = (1e-3, 86_400.0);
/// `--resend-s`' range (s): at least a millisecond (a faster resend floods the peer without
/// giving its answer time to come), at most a minute.
pub const RESEND_RANGE_S: (f64, f64) = (1e-3, 60.0);

impl HilOptions {
    /// Every duration within its range: an error naming the flag.
    pub fn check(&self) -> Result<(), (String, String)> {
        let flags = [
            ("--wait-s", self.wait_s, WAIT_RANGE_S),
            ("--stall-timeout-s", self.stall_timeout_s, WAIT_RANGE_S),
            ("--resend-s", self.resend_s, RESEND_RANGE_S),
        ];
        for (flag, v, (lo, hi)) in flags {
            if !(lo..=hi).contains(&v) {
                let v = crate::error::num(v);
                return Err((flag.into(), format!("must be in {lo}..={hi} s, got {v}")));
            }
        }
        Ok(())
    }
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
    /// The peer's `exoleg_reset` status has come (its own COMMAND, or the first step's).
    reset_done: bool,
    /// COMMANDs whose reported compute time was longer than their round trip (taken as the
    /// round trip: a peer cannot compute longer than the plant waited).
    compute_clamped: usize,
}

impl HilController {
    /// Listen, wait for the peer's HELLO and READY: the controller of a run (errors say what
    /// went wrong: nobody came, a refused HELLO, a refused instance).
    pub fn connect(setup: &InstanceSetup, log_names: Vec<String>, opts: HilOptions) -> Result<Self, String> {
        let link = Link::bind(&opts.listen, opts.allow_from.clone())?;
        Self::on_link(link, setup, log_names, opts)
    }

    /// Bind first (to print the address), then [`Self::on_link`].
    pub fn bind(opts: &HilOptions) -> Result<Link, String> {
        Link::bind(&opts.listen, opts.allow_from.clone())
    }

    /// The peer that drives the run, for reports ("HIL peer ADDR:PORT").
    pub fn peer_name(&self) -> String {
        self.status.name.clone()
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
            reset_done: false,
            compute_clamped: 0,
        })
    }

    fn stop(&self, seq: u64, t_s: f64, why: String) -> ControlStop {
        ControlStop::crash(format!("{} at sample {seq} (t = {t_s:.6} s): {why}", self.status.name))
    }

    fn send_readings(&mut self, s: &SampleInput, seq: u64) -> Result<(), ControlStop> {
        let r = crate::control::plugin::readings_of(s);
        let h = Header { kind: MsgType::Readings, seq, sim_time_ns: wire::time_ns(s.t_s) };
        self.link.send(&h, &Message::Readings(Box::new(r))).map_err(|e| self.stop(seq, s.t_s, e))
    }

    /// Take a COMMAND for the current sample, which left `round_trip` ago: a reset's status
    /// (None: the step's COMMAND is still to come), or the step's output. The compute time it
    /// reports is at most the round trip.
    fn accept(
        &mut self,
        status: i32,
        call: u32,
        compute_ns: u64,
        command: ExolegCommand,
        round_trip: Duration,
    ) -> Result<Option<ControlOutput>, ControlStop> {
        self.command = command;
        self.last_valid = Instant::now();
        if call == wire::CALL_RESET {
            // The reset's own COMMAND (a peer may send it, whatever its status, before the
            // step's): taken as in-process, a warning counted, a stop the end.
            self.reset_done = true;
            self.status.take("exoleg_reset", status, || message_text(&command.message))?;
            return Ok(None);
        }
        self.reset_done = true;
        let rt = round_trip.as_secs_f64();
        let compute = compute_ns as f64 * 1e-9;
        self.compute_clamped += usize::from(compute > rt);
        self.compute_s.push(compute.min(rt));
        self.round_trip_s.push(rt);
        self.status.take("exoleg_step", status, || message_text(&command.message))?;
        output_of(&self.status.name, &self.command, status).map(Some)
    }

    /// Lockstep: send, wait (resending) for this sample's COMMAND. Both timers run from what
    /// the run did, whatever else arrives: the resend from the last READINGS sent, the stall
    /// watchdog from the last valid COMMAND (a peer repeating its last COMMAND, or saying
    /// HELLO, stops neither); a pause of this process restarts both.
    fn lockstep(&mut self, s: &SampleInput, seq: u64) -> Result<ControlOutput, ControlStop> {
        let t0 = Instant::now();
        self.send_readings(s, seq)?;
        let resend = Duration::from_secs_f64(self.opts.resend_s);
        let stall = Duration::from_secs_f64(self.opts.stall_timeout_s);
        let mut sent_at = t0;
        loop {
            let next = (sent_at + resend).min(self.last_valid + stall);
            let wait = next.saturating_duration_since(Instant::now());
            let got = self.link.receive(wait).map_err(|e| self.stop(seq, s.t_s, e))?.0;
            if self.link.take_pause() {
                (sent_at, self.last_valid) = (Instant::now(), Instant::now());
            }
            match got {
                Received::Message(h, Message::Command { status, call, compute_ns, command }) if h.seq == seq => {
                    let answered = call == wire::CALL_STEP || !self.reset_done;
                    if answered {
                        if let Some(out) = self.accept(status, call, compute_ns, *command, t0.elapsed())? {
                            return Ok(out);
                        }
                        continue;
                    }
                    self.link.counts.duplicated += 1;
                }
                Received::Message(h, Message::Command { .. }) if h.seq < seq => self.link.counts.duplicated += 1,
                Received::Message(_, Message::Command { .. }) => self.link.counts.out_of_order += 1,
                Received::Message(..) => self.link.counts.unexpected += 1,
                Received::Timeout => {}
            }
            let now = Instant::now();
            if now >= self.last_valid + stall {
                return Err(self.stalled(seq, s.t_s));
            }
            if now >= sent_at + resend {
                self.link.counts.resent += 1;
                self.send_readings(s, seq)?;
                sent_at = Instant::now();
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
            if self.link.take_pause() {
                // Stopped and continued: the peer's silence while this process slept is no stall.
                self.last_valid = Instant::now();
            }
            match got {
                Received::Message(h, Message::Command { status, call, compute_ns, command }) => {
                    let k = h.seq as usize;
                    match self.sent.get_mut(k) {
                        Some((_, true)) => self.link.counts.duplicated += 1,
                        Some((at, _)) if k == i && call == wire::CALL_RESET && !self.reset_done => {
                            let rt = at.elapsed();
                            self.accept(status, call, compute_ns, *command, rt)?;
                        }
                        Some((at, answered)) if k == i => {
                            *answered = true;
                            let rt = at.elapsed();
                            if let Some(out) = self.accept(status, call, compute_ns, *command, rt)? {
                                return Ok(out);
                            }
                        }
                        Some((at, answered)) => {
                            *answered = true;
                            self.round_trip_s.push(at.elapsed().as_secs_f64());
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
            "strangers": c.strangers,
            "pauses": c.pauses,
            "compute_clamped": self.compute_clamped,
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
