//! The bench thread's CPU time (`CLOCK_THREAD_CPUTIME_ID`) for criterion benches. On a shared,
//! loaded machine wall time also counts the time other processes hold the core; this clock
//! says what one core does. For benches only (a dev-dependency): it depends on nothing of ours,
//! so every layer may use it.

use std::time::Duration;

/// CPU time of the calling thread.
pub fn thread_cpu() -> Duration {
    let mut now = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `now` is a valid, writable timespec; the clock id is a constant Linux supports.
    let status = unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut now) };
    assert_eq!(status, 0, "CLOCK_THREAD_CPUTIME_ID unavailable");
    Duration::new(
        u64::try_from(now.tv_sec).unwrap_or(0),
        u32::try_from(now.tv_nsec).unwrap_or(0),
    )
}

/// Times `one` in this thread's CPU time (criterion's `iter_custom`).
pub fn cpu_iter<R>(bench: &mut criterion::Bencher<'_>, mut one: impl FnMut() -> R) {
    bench.iter_custom(|iters| {
        let start = thread_cpu();
        for _ in 0..iters {
            std::hint::black_box(one());
        }
        thread_cpu() - start
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_clock_counts_this_threads_work_and_not_its_sleep() {
        let start = thread_cpu();
        std::thread::sleep(Duration::from_millis(50));
        let slept = thread_cpu() - start;
        let start = thread_cpu();
        let mut x = 0u64;
        while thread_cpu() - start < Duration::from_millis(5) {
            x = std::hint::black_box(x.wrapping_add(1));
        }
        let spun = thread_cpu() - start;
        assert!(x > 0);
        // 50 ms asleep cost less CPU than 5 ms of spinning (a wall clock would say 10x more).
        assert!(slept < spun, "slept {slept:?}, spun {spun:?}");
    }
}
