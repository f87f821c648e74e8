//! Zero-order hold: a value computed at sample instants and held between them.

/// Samples every `every` fixed steps and holds a value in between (Drake's `ZeroOrderHold`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ZeroOrderHold<T> {
    every: usize,
    value: T,
}

impl<T: Copy> ZeroOrderHold<T> {
    /// A hold sampling every `every` (>= 1) steps, holding `initial` until the first sample.
    pub fn new(every: usize, initial: T) -> Self {
        Self { every: every.max(1), value: initial }
    }

    /// Whether step `k` is a sample instant.
    pub fn is_sample(&self, k: usize) -> bool {
        k.is_multiple_of(self.every)
    }

    /// The held value.
    pub fn value(&self) -> T {
        self.value
    }

    /// Hold a new value (at a sample instant).
    pub fn set(&mut self, v: T) {
        self.value = v;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn samples_every_nth_step_and_holds() {
        let mut h = ZeroOrderHold::new(4, 0.0);
        let samples: Vec<usize> = (0..10).filter(|k| h.is_sample(*k)).collect();
        assert_eq!(samples, vec![0, 4, 8]);
        h.set(2.5);
        assert_eq!(h.value(), 2.5);
    }
}
