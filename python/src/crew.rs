//! A crew of worker threads that apply one function to every item of a fixed set, the calling
//! thread working with them ([`Crew::run`]). Made for calls of a few microseconds each (a
//! vector environment's step): the workers stay for the crew's life and wait for the next call
//! awake for a moment, then parked; a call allocates nothing.
//!
//! Each thread has its own contiguous chunk of items and, done with it, takes the items no one
//! has started from the others' chunks: a worker that the system has not scheduled yet (other
//! processes on the cores) never holds the call up, since the caller then does its items.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

/// How long a waiting thread stays awake before it parks: about the time between two steps
/// of a tight loop, so that back-to-back calls wake no one.
const SPIN: Duration = Duration::from_micros(60);

/// A counter on a cache line of its own (the threads' claims do not slow each other).
#[repr(align(64))]
struct Counter(AtomicUsize);

/// What the caller and the workers share.
struct Shared<T> {
    items: Vec<Mutex<T>>,
    /// Each thread's chunk of `items` (start, end).
    chunks: Vec<(usize, usize)>,
    /// Each chunk's next unclaimed item in the current call.
    next: Vec<Counter>,
    /// Items done in the current call.
    finished: AtomicUsize,
    /// The call number: the workers start when it changes.
    go: AtomicU64,
    /// The crew is dropped: the workers end.
    stop: AtomicBool,
    /// The thread that made the current call (woken when the last item is done).
    caller: Mutex<Option<Thread>>,
    /// A panic in the current call, as text.
    panic: Mutex<Option<String>>,
    f: fn(&mut T),
}

/// Lock `m`, poisoned or not (every lock here holds plain data that a panic leaves whole).
fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(PoisonError::into_inner)
}

/// Wait until `ready()`: yield the core for [`SPIN`] (to the thread it waits for, when both
/// share a core: spinning there would only delay it), then park (the notifier sets what
/// `ready` reads, then unparks this thread).
fn wait_until(ready: impl Fn() -> bool) {
    let start = Instant::now();
    while !ready() {
        if start.elapsed() > SPIN {
            while !ready() {
                std::thread::park();
            }
            return;
        }
        std::thread::yield_now();
    }
}

/// A panic's message.
fn panic_text(p: &(dyn std::any::Any + Send)) -> String {
    p.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| p.downcast_ref::<String>().cloned()).unwrap_or_default()
}

impl<T> Shared<T> {
    /// Thread `k`'s part of a call: the items of its chunk, then those left in the others'.
    /// Returns true when it did the call's last item.
    fn drain(&self, k: usize) -> bool {
        let n = self.chunks.len();
        let mut last = false;
        for c in (0..n).map(|j| (k + j) % n) {
            let end = self.chunks[c].1;
            loop {
                let i = self.next[c].0.fetch_add(1, Ordering::AcqRel);
                if i >= end {
                    break;
                }
                let mut item = lock(&self.items[i]);
                if let Err(p) = catch_unwind(AssertUnwindSafe(|| (self.f)(&mut item))) {
                    *lock(&self.panic) = Some(panic_text(&*p));
                }
                drop(item);
                last = self.finished.fetch_add(1, Ordering::AcqRel) + 1 == self.items.len();
            }
        }
        last
    }

    /// A worker (thread `k`): its part of every call until the crew is dropped.
    fn work(&self, k: usize) {
        let mut seen = 0;
        loop {
            wait_until(|| self.go.load(Ordering::Acquire) != seen || self.stop.load(Ordering::Acquire));
            if self.stop.load(Ordering::Acquire) {
                return;
            }
            seen = self.go.load(Ordering::Acquire);
            if self.drain(k) {
                if let Some(t) = lock(&self.caller).as_ref() {
                    t.unpark();
                }
            }
        }
    }
}

/// Items that a call of [`Crew::run`] hands to the calling thread and the workers.
pub struct Crew<T: Send + 'static> {
    shared: Arc<Shared<T>>,
    workers: Vec<(Thread, JoinHandle<()>)>,
    /// The process that started the workers (a forked child has none of them: it does every
    /// item itself).
    pid: u32,
}

impl<T: Send + 'static> Crew<T> {
    /// `items` in `threads` chunks (at most one per item; sizes differing by at most one),
    /// with a worker thread for each chunk but the first (the caller's); [`Self::run`] applies
    /// `f` to every item.
    pub fn new(items: Vec<T>, threads: usize, f: fn(&mut T)) -> std::io::Result<Self> {
        let n = items.len();
        let threads = threads.clamp(1, n.max(1));
        let mut start = 0;
        let chunks: Vec<(usize, usize)> = (0..threads)
            .map(|k| {
                let len = n / threads + usize::from(k < n % threads);
                start += len;
                (start - len, start)
            })
            .collect();
        let shared = Arc::new(Shared {
            items: items.into_iter().map(Mutex::new).collect(),
            next: chunks.iter().map(|c| Counter(AtomicUsize::new(c.1))).collect(),
            chunks,
            finished: AtomicUsize::new(0),
            go: AtomicU64::new(0),
            stop: AtomicBool::new(false),
            caller: Mutex::new(None),
            panic: Mutex::new(None),
            f,
        });
        let mut crew = Self { shared, workers: Vec::new(), pid: std::process::id() };
        for k in 1..threads {
            let shared = crew.shared.clone();
            let h = std::thread::Builder::new().name(format!("exoleg-vec-{k}")).spawn(move || shared.work(k))?;
            crew.workers.push((h.thread().clone(), h));
        }
        Ok(crew)
    }

    /// Threads that do the items (the caller's included).
    pub fn threads(&self) -> usize {
        self.shared.chunks.len()
    }

    /// Apply `f` to every item once, the threads in parallel (this one included); returns
    /// when all are done. A panic in `f` is returned as its message.
    pub fn run(&self) -> Result<(), String> {
        let s = &self.shared;
        let helped = !self.workers.is_empty() && std::process::id() == self.pid;
        if helped {
            // First: a worker still finishing its claims of the last call may do this one's
            // last item, and wakes whoever is here.
            *lock(&s.caller) = Some(std::thread::current());
        }
        s.finished.store(0, Ordering::Release);
        for (c, (start, _)) in s.next.iter().zip(&s.chunks) {
            c.0.store(*start, Ordering::Release);
        }
        if helped {
            s.go.fetch_add(1, Ordering::AcqRel);
            self.workers.iter().for_each(|(t, _)| t.unpark());
        }
        s.drain(0);
        wait_until(|| s.finished.load(Ordering::Acquire) == s.items.len());
        lock(&s.panic).take().map_or(Ok(()), Err)
    }

    /// Visit every item in order, on this thread.
    pub fn for_each(&self, mut f: impl FnMut(usize, &mut T)) {
        for (i, item) in self.shared.items.iter().enumerate() {
            f(i, &mut lock(item));
        }
    }
}

impl<T: Send + 'static> Drop for Crew<T> {
    fn drop(&mut self) {
        if std::process::id() != self.pid {
            // A forked child: the workers are its parent's, not to be joined here.
            std::mem::forget(std::mem::take(&mut self.workers));
            return;
        }
        self.shared.stop.store(true, Ordering::Release);
        for (t, h) in self.workers.drain(..) {
            t.unpark();
            let _ = h.join();
        }
    }
}
