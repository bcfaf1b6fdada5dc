//! Running a few independent jobs of uneven size on all cores.
//!
//! Detection ends its stages with a handful of jobs (the leftover pieces of a scan, the
//! pieces of a split region) whose sizes differ by 10× or more. Handed to rayon as a
//! plain parallel iterator, they are split in halves: a thread that wakes late finds
//! only the right half left, or nothing. [`map_largest_first`] makes each job its own
//! task and starts the largest first (longest-processing-time order), so the last job
//! to finish is a small one.

use std::cmp::Reverse;

use rayon::prelude::*;

/// `items.map(job)` in the order of `items`, the jobs run in parallel, largest `size`
/// first (ties in input order), one task each. The result does not depend on the
/// thread count: each job sees only its own item.
pub(crate) fn map_largest_first<T, R>(
    items: Vec<T>,
    size: impl Fn(&T) -> usize,
    job: impl Fn(T) -> R + Sync + Send,
) -> Vec<R>
where
    T: Send,
    R: Send,
{
    let mut jobs: Vec<(usize, T)> = items.into_iter().enumerate().collect();
    jobs.sort_by_cached_key(|(k, item)| (Reverse(size(item)), *k));
    let mut done: Vec<(usize, R)> = jobs
        .into_par_iter()
        .with_max_len(1)
        .map(|(k, item)| (k, job(item)))
        .collect();
    done.sort_unstable_by_key(|(k, _)| *k);
    done.into_iter().map(|(_, r)| r).collect()
}

#[cfg(test)]
mod tests {
    use std::sync::Mutex;

    use super::*;

    #[test]
    fn results_come_in_input_order_and_the_largest_job_starts_first() {
        let sizes = vec![3usize, 40, 1, 40, 7, 0, 12];
        let started = Mutex::new(Vec::new());
        let one_thread = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let out = one_thread.install(|| {
            map_largest_first(
                sizes.clone(),
                |&s| s,
                |s| {
                    started.lock().unwrap().push(s);
                    s * 10
                },
            )
        });
        assert_eq!(out, vec![30, 400, 10, 400, 70, 0, 120]);
        // One thread runs the jobs in the order they are scheduled.
        assert_eq!(started.into_inner().unwrap(), vec![40, 40, 12, 7, 3, 1, 0]);
    }

    #[test]
    fn the_result_does_not_depend_on_the_thread_count() {
        let items: Vec<Vec<u64>> = (0..50u64)
            .map(|k| (0..(k * 37 % 23)).map(|j| j * k).collect())
            .collect();
        let run = |threads: usize| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| map_largest_first(items.clone(), Vec::len, |v| v.iter().sum::<u64>()))
        };
        let expected: Vec<u64> = items.iter().map(|v| v.iter().sum()).collect();
        assert_eq!(run(1), expected);
        assert_eq!(run(3), expected);
    }
}
