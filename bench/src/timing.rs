//! Timing side by side: every repetition runs one batch of each case in
//! turn, so that a busy spell of a shared machine slows all cases alike;
//! the driver then takes medians over repetitions, and ratios per
//! repetition before their median.

use std::hint::black_box;
use std::time::{Duration, Instant};

/// One thing to time: a name and one call.
pub struct Case<'a> {
    /// The name in the results.
    pub name: String,
    /// One call of what is timed.
    pub call: Box<dyn FnMut() + 'a>,
}

/// The number of calls that take at least `target` (doubling from 1).
fn calls_per_batch(call: &mut dyn FnMut(), target: Duration) -> u64 {
    let mut calls = 1u64;
    loop {
        let start = Instant::now();
        for _ in 0..calls {
            call();
        }
        if start.elapsed() >= target || calls >= 1 << 40 {
            return calls;
        }
        calls *= 2;
    }
}

/// Nanoseconds per call of each case, one entry per repetition:
/// `result[case][repetition]`. Each batch lasts about `batch`.
pub fn interleaved(cases: &mut [Case], repetitions: usize, batch: Duration) -> Vec<Vec<f64>> {
    let calls: Vec<u64> = cases.iter_mut().map(|case| calls_per_batch(&mut case.call, batch)).collect();
    let mut times = vec![Vec::with_capacity(repetitions); cases.len()];
    for repetition in 0..repetitions {
        // Rotate which case goes first, so that none always follows the same neighbour.
        for k in 0..cases.len() {
            let index = (k + repetition) % cases.len();
            let case = &mut cases[index];
            let start = Instant::now();
            for _ in 0..calls[index] {
                (case.call)();
            }
            let elapsed = black_box(start.elapsed());
            times[index].push(elapsed.as_nanos() as f64 / calls[index] as f64);
        }
    }
    times
}
