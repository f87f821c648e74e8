//! A crew of worker threads that run one function over a fixed set of items, split in
//! contiguous chunks, with the calling thread taking the first chunk ([`Crew::run`]). Made for
//! calls of a few microseconds each (a vector environment's step): the workers stay for the
//! crew's life, wait for the next call spinning briefly and then parked, and a call allocates
//! nothing.

use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, MutexGuard, PoisonError};
use std::thread::{JoinHandle, Thread};
use std::time::{Duration, Instant};

/// How long a waiting thread stays awake before it parks: about the time between two steps
/// of a tight loop, so that back-to-back calls wake no one.
const SPIN: Duration = Duration::from_micros(60);

/// What the caller and the workers share.
struct Shared {
    /// The call number: a worker runs its chunk when it changes.
    go: AtomicU64,
    /// Workers done with the current call.
    done: AtomicUsize,
    /// The crew is dropped: the workers end.
    stop: AtomicBool,
    /// The thread that made the current call (woken when the last worker is done).
    caller: Mutex<Option<Thread>>,
    /// A worker's panic in the current call, as text.
    panic: Mutex<Option<String>>,
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

/// Run `f` over a chunk; a panic becomes its message.
fn run_chunk<T>(chunk: &Mutex<Vec<T>>, f: fn(&mut T)) -> Result<(), String> {
    let mut items = lock(chunk);
    catch_unwind(AssertUnwindSafe(|| items.iter_mut().for_each(f))).map_err(|p| panic_text(&*p))
}

/// A worker: run `f` over `chunk` at every call until the crew is dropped.
fn work<T>(shared: &Shared, chunk: &Mutex<Vec<T>>, f: fn(&mut T)) {
    let mut seen = 0;
    loop {
        wait_until(|| shared.go.load(Ordering::Acquire) != seen || shared.stop.load(Ordering::Acquire));
        if shared.stop.load(Ordering::Acquire) {
            return;
        }
        seen = shared.go.load(Ordering::Acquire);
        if let Err(m) = run_chunk(chunk, f) {
            *lock(&shared.panic) = Some(m);
        }
        shared.done.fetch_add(1, Ordering::AcqRel);
        if let Some(t) = lock(&shared.caller).as_ref() {
            t.unpark();
        }
    }
}

/// Items split in chunks, one a thread: the caller's (the first) and one per worker.
pub struct Crew<T: Send + 'static> {
    chunks: Vec<Arc<Mutex<Vec<T>>>>,
    f: fn(&mut T),
    shared: Arc<Shared>,
    workers: Vec<(Thread, JoinHandle<()>)>,
    /// The process that started the workers (a forked child has none of them: it runs every
    /// chunk itself).
    pid: u32,
}

impl<T: Send + 'static> Crew<T> {
    /// `items` split in `threads` chunks (at most one per item; sizes differing by at most
    /// one), with a worker thread for each chunk but the first; [`Self::run`] applies `f`.
    pub fn new(items: Vec<T>, threads: usize, f: fn(&mut T)) -> std::io::Result<Self> {
        let n = items.len();
        let threads = threads.clamp(1, n.max(1));
        let mut rest = items.into_iter();
        let chunks: Vec<Arc<Mutex<Vec<T>>>> = (0..threads)
            .map(|k| Arc::new(Mutex::new(rest.by_ref().take(n / threads + usize::from(k < n % threads)).collect())))
            .collect();
        let shared = Arc::new(Shared {
            go: AtomicU64::new(0),
            done: AtomicUsize::new(0),
            stop: AtomicBool::new(false),
            caller: Mutex::new(None),
            panic: Mutex::new(None),
        });
        let mut crew = Self { chunks, f, shared, workers: Vec::new(), pid: std::process::id() };
        for (k, chunk) in crew.chunks.iter().enumerate().skip(1) {
            let (shared, chunk) = (crew.shared.clone(), chunk.clone());
            let h =
                std::thread::Builder::new().name(format!("exoleg-vec-{k}")).spawn(move || work(&shared, &chunk, f))?;
            crew.workers.push((h.thread().clone(), h));
        }
        Ok(crew)
    }

    /// Threads that run the items (the caller's included).
    pub fn threads(&self) -> usize {
        self.chunks.len()
    }

    /// Apply `f` to every item once, the chunks in parallel (this thread takes the first);
    /// returns when all are done. A panic in `f` is returned as its message.
    pub fn run(&self) -> Result<(), String> {
        if std::process::id() != self.pid {
            return self.chunks.iter().try_for_each(|c| run_chunk(c, self.f));
        }
        let s = &self.shared;
        if !self.workers.is_empty() {
            *lock(&s.caller) = Some(std::thread::current());
            s.done.store(0, Ordering::Release);
            s.go.fetch_add(1, Ordering::AcqRel);
            self.workers.iter().for_each(|(t, _)| t.unpark());
        }
        let mine = run_chunk(&self.chunks[0], self.f);
        wait_until(|| s.done.load(Ordering::Acquire) == self.workers.len());
        match (mine, lock(&s.panic).take()) {
            (Err(m), _) | (Ok(()), Some(m)) => Err(m),
            (Ok(()), None) => Ok(()),
        }
    }

    /// Visit every item in order, on this thread.
    pub fn for_each(&self, mut f: impl FnMut(usize, &mut T)) {
        let mut i = 0;
        for c in &self.chunks {
            for item in lock(c).iter_mut() {
                f(i, item);
                i += 1;
            }
        }
    }
}

impl<T: Send + 'static> Drop for Crew<T> {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Release);
        for (t, h) in self.workers.drain(..) {
            t.unpark();
            let _ = h.join();
        }
    }
}
