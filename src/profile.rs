//! Where a step's time goes, per stage of the loop (issue 41's cost table): the plant's
//! mechanics, its ground contact, the hydraulics, the sensors, the controller, the
//! references, the wearer, the online metrics and the recording of rows.
//!
//! Compiled in only with the cargo feature `stage-timing` (`cargo build --release --features
//! stage-timing`); without it [`scope`] is an empty value the optimiser removes, and the loop
//! is the one the speed figures measure. With it, each timed region takes the wall clock at its
//! start and end and books its time to its stage *exclusively* (a region's time less the
//! regions timed inside it: contact inside the plant, the reference inside a hydraulic stage),
//! summed over every thread of the process; the binary prints the table at exit
//! (`scripts/stage-costs` runs the cases of the README's table). Each timed region costs two
//! clock reads and some bookkeeping (about 40-60 ns on the machines we measured); [`report`]
//! measures that overhead at the end of the run and subtracts it per region, and says how much
//! it subtracted. "Loop, untimed" is the rest of the step: the integrator, the state's copies
//! and checks, the faults' bookkeeping.

/// A stage of the loop (in [`STAGES`]' order: its index there).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// The leg's mechanics: kinematics, mass matrix and solve (reduced engine), or Rapier's
    /// step (its contact included).
    Plant,
    /// The reduced engine's ground contact (spheres, compliant law, friction anchors).
    Contact,
    /// The cylinder's force ODE, valve, friction and end stops.
    Hydraulics,
    /// The sensors' readings (the controller's and the device's own).
    Sensors,
    /// The controller's update (sampled) or derivative (continuous).
    Controller,
    /// The desired force and knee trajectory (gait fits, outer loop).
    Reference,
    /// The wearer: the body's force laws, the muscle wearer or the muscle analysis.
    Wearer,
    /// The online metrics (summary, walking, wearer, safety, muscles).
    Metrics,
    /// Handing the row to the output (the CSV or Parquet writer's queue).
    Recording,
}

/// Every stage, in the table's order.
pub const STAGES: [Stage; 9] = [
    Stage::Plant,
    Stage::Contact,
    Stage::Hydraulics,
    Stage::Sensors,
    Stage::Controller,
    Stage::Reference,
    Stage::Wearer,
    Stage::Metrics,
    Stage::Recording,
];

impl Stage {
    /// The name in the table.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Plant => "plant",
            Stage::Contact => "contact",
            Stage::Hydraulics => "hydraulics",
            Stage::Sensors => "sensors",
            Stage::Controller => "controller",
            Stage::Reference => "reference",
            Stage::Wearer => "wearer",
            Stage::Metrics => "metrics",
            Stage::Recording => "recording",
        }
    }
}

#[cfg(feature = "stage-timing")]
mod on {
    use super::{Stage, STAGES};
    use std::cell::RefCell;
    use std::sync::atomic::{AtomicU64, Ordering::Relaxed};
    use std::time::Instant;

    pub(super) static NS: [AtomicU64; STAGES.len()] = [const { AtomicU64::new(0) }; STAGES.len()];
    pub(super) static COUNT: [AtomicU64; STAGES.len()] = [const { AtomicU64::new(0) }; STAGES.len()];
    /// Per stage, how many regions closed inside one of its regions.
    pub(super) static CHILDREN: [AtomicU64; STAGES.len()] = [const { AtomicU64::new(0) }; STAGES.len()];
    pub(super) static STEPS: AtomicU64 = AtomicU64::new(0);
    pub(super) static LOOP_NS: AtomicU64 = AtomicU64::new(0);

    thread_local! {
        /// The open regions: their start, the time of the regions closed inside them (ns) and
        /// their stage's index.
        static OPEN: RefCell<Vec<(Instant, u64, usize)>> = const { RefCell::new(Vec::new()) };
    }

    /// An open timed region; closing (dropping) it books its time.
    pub struct Scope;

    pub(super) fn open(stage: Stage) -> Scope {
        OPEN.with_borrow_mut(|o| o.push((Instant::now(), 0, stage as usize)));
        Scope
    }

    impl Drop for Scope {
        fn drop(&mut self) {
            let end = Instant::now();
            OPEN.with_borrow_mut(|o| {
                let Some((start, inner, i)) = o.pop() else { return };
                let total = end.duration_since(start).as_nanos() as u64;
                NS[i].fetch_add(total.saturating_sub(inner), Relaxed);
                COUNT[i].fetch_add(1, Relaxed);
                if let Some(parent) = o.last_mut() {
                    parent.1 += total;
                    CHILDREN[parent.2].fetch_add(1, Relaxed);
                }
            });
        }
    }

    /// The time a region books to itself when empty and the time it adds to its parent
    /// (ns per region, the median of 16 rounds of 20,000), measured on this thread with the
    /// stages' counters saved and restored: call it when no other thread is timing.
    pub(super) fn overhead_ns() -> (f64, f64) {
        let n = 20_000u64;
        let saved: Vec<[u64; 3]> = (0..STAGES.len())
            .map(|i| [NS[i].load(Relaxed), COUNT[i].load(Relaxed), CHILDREN[i].load(Relaxed)])
            .collect();
        let (mut own, mut leak) = (Vec::new(), Vec::new());
        for _ in 0..16 {
            let before = [NS[0].load(Relaxed), NS[1].load(Relaxed)];
            for _ in 0..n {
                let _outer = open(Stage::Plant);
                let _inner = open(Stage::Contact);
            }
            // The empty inner region's own time, and what it added to its (otherwise empty)
            // parent's exclusive time beyond the parent's own.
            let inner = (NS[1].load(Relaxed) - before[1]) as f64 / n as f64;
            let outer = (NS[0].load(Relaxed) - before[0]) as f64 / n as f64;
            own.push(inner);
            leak.push((outer - inner).max(0.0));
        }
        for (i, [ns, count, children]) in saved.into_iter().enumerate() {
            NS[i].store(ns, Relaxed);
            COUNT[i].store(count, Relaxed);
            CHILDREN[i].store(children, Relaxed);
        }
        own.sort_by(f64::total_cmp);
        leak.sort_by(f64::total_cmp);
        (own[8], leak[8])
    }
}

/// A timed region of `stage` (until dropped); nothing without the feature `stage-timing`.
#[cfg(feature = "stage-timing")]
#[inline]
pub fn scope(stage: Stage) -> impl Drop {
    on::open(stage)
}

/// A timed region of `stage` (until dropped); nothing without the feature `stage-timing`.
#[cfg(not(feature = "stage-timing"))]
#[inline(always)]
pub fn scope(_stage: Stage) -> Untimed {
    Untimed
}

/// What [`scope`] gives without the feature `stage-timing`: nothing.
#[cfg(not(feature = "stage-timing"))]
pub struct Untimed;

/// Count `steps` steps of a loop that took `loop_ns` (ns) of wall time (the loops' totals
/// the table divides by).
#[inline]
pub fn count_loop(steps: u64, loop_ns: u64) {
    #[cfg(feature = "stage-timing")]
    {
        on::STEPS.fetch_add(steps, std::sync::atomic::Ordering::Relaxed);
        on::LOOP_NS.fetch_add(loop_ns, std::sync::atomic::Ordering::Relaxed);
    }
    let _ = (steps, loop_ns);
}

/// The table of the stages' times so far: per stage the ns per step (timer overhead
/// subtracted) and its share of the loop, the loop's untimed rest, and the totals. None without
/// the feature or before a step.
pub fn report() -> Option<String> {
    #[cfg(feature = "stage-timing")]
    {
        use std::fmt::Write;
        use std::sync::atomic::Ordering::Relaxed;
        let steps = on::STEPS.load(Relaxed);
        if steps == 0 {
            return None;
        }
        let (own, leak) = on::overhead_ns();
        let per_step = |ns: f64| ns / steps as f64;
        let loop_ns = per_step(on::LOOP_NS.load(Relaxed) as f64);
        let mut out = String::new();
        let _ = writeln!(out, "{:<16} {:>12} {:>8} {:>14}", "stage", "ns per step", "share", "regions/step");
        let (mut timed, mut regions, mut rows) = (0.0, 0.0, Vec::new());
        for (i, s) in STAGES.iter().enumerate() {
            let count = per_step(on::COUNT[i].load(Relaxed) as f64);
            let children = per_step(on::CHILDREN[i].load(Relaxed) as f64);
            // Its regions' own overhead and what its children's added to it.
            let ns = (per_step(on::NS[i].load(Relaxed) as f64) - own * count - leak * children).max(0.0);
            timed += ns;
            regions += count;
            rows.push((s.name(), ns, count));
        }
        // The overhead of every region, inside and outside its own interval, is not the loop's.
        let loop_net = loop_ns - regions * (own + leak);
        let rest = (loop_net - timed).max(0.0);
        for (name, ns, count) in rows {
            let _ = writeln!(out, "{:<16} {:>12.0} {:>7.1}% {:>14.2}", name, ns, 100.0 * ns / loop_net, count);
        }
        let _ = writeln!(out, "{:<16} {:>12.0} {:>7.1}%", "loop, untimed", rest, 100.0 * rest / loop_net);
        let _ = writeln!(
            out,
            "{:<16} {:>12.0}          ({} steps; timer overhead {:.0} + {:.0} ns per region subtracted: {:.0} ns per step)",
            "whole step",
            loop_net,
            steps,
            own,
            leak,
            regions * (own + leak)
        );
        Some(out)
    }
    #[cfg(not(feature = "stage-timing"))]
    None
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A stage's index in the counters is its place in [`STAGES`]; the names are distinct.
    #[test]
    fn stages_index_their_table() {
        for (i, s) in STAGES.iter().enumerate() {
            assert_eq!(*s as usize, i, "{}", s.name());
        }
        let names: std::collections::BTreeSet<_> = STAGES.iter().map(|s| s.name()).collect();
        assert_eq!(names.len(), STAGES.len());
        assert!(report().is_none() || cfg!(feature = "stage-timing"));
    }
}
