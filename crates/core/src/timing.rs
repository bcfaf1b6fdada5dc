//! Wall time per stage of a run, in the order the stages ran: what `primfit fit -v` and
//! `--timings` report and what `scripts/bench.sh` tabulates.

use std::time::Instant;

use serde_json::{Value, json};

/// Seconds of wall time per named stage, in the order they ran. Names are dotted paths
/// (`detect.normals`): a stage of a stage.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StageTimes {
    stages: Vec<(String, f64)>,
}

impl StageTimes {
    /// No stages yet.
    pub fn new() -> Self {
        StageTimes::default()
    }

    /// Appends `stage`, which took `seconds`; a stage already present accumulates.
    pub fn add(&mut self, stage: &str, seconds: f64) {
        match self.stages.iter_mut().find(|(s, _)| s == stage) {
            Some((_, t)) => *t += seconds,
            None => self.stages.push((stage.to_string(), seconds)),
        }
    }

    /// Appends every stage of `other`, its names prefixed by `prefix.`.
    pub fn add_all(&mut self, prefix: &str, other: &StageTimes) {
        for (stage, seconds) in &other.stages {
            self.add(&format!("{prefix}.{stage}"), *seconds);
        }
    }

    /// The stages, in the order they first ran.
    pub fn iter(&self) -> impl Iterator<Item = (&str, f64)> {
        self.stages.iter().map(|(s, t)| (s.as_str(), *t))
    }

    /// Seconds of `stage`, if it ran.
    pub fn get(&self, stage: &str) -> Option<f64> {
        self.iter().find(|(s, _)| *s == stage).map(|(_, t)| t)
    }

    /// Whether no stage ran.
    pub fn is_empty(&self) -> bool {
        self.stages.is_empty()
    }

    /// `[{"stage": name, "seconds": t}, …]`, in order.
    pub fn to_json(&self) -> Value {
        Value::Array(
            self.iter()
                .map(|(s, t)| json!({"stage": s, "seconds": t}))
                .collect(),
        )
    }

    /// `name 0.12 s, name 1.30 s, …` for a log line.
    pub fn summary(&self) -> String {
        let parts: Vec<String> = self.iter().map(|(s, t)| format!("{s} {t:.3} s")).collect();
        parts.join(", ")
    }
}

/// Times consecutive stages: each [`Stopwatch::lap`] records the time since the
/// previous lap (or the start) under a stage name.
#[derive(Debug)]
pub struct Stopwatch {
    last: Instant,
    /// The stages timed so far.
    pub times: StageTimes,
}

impl Default for Stopwatch {
    fn default() -> Self {
        Stopwatch::start()
    }
}

impl Stopwatch {
    /// Starts timing now.
    pub fn start() -> Self {
        Stopwatch {
            last: Instant::now(),
            times: StageTimes::new(),
        }
    }

    /// Records the time since the last lap as `stage`; returns it (seconds).
    pub fn lap(&mut self, stage: &str) -> f64 {
        let now = Instant::now();
        let seconds = (now - self.last).as_secs_f64();
        self.last = now;
        self.times.add(stage, seconds);
        seconds
    }

    /// Records `inner`'s stages under `prefix.` and restarts the lap clock, so the
    /// time they cover is not counted twice.
    pub fn nest(&mut self, prefix: &str, inner: &StageTimes) {
        self.times.add_all(prefix, inner);
        self.last = Instant::now();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stages_keep_their_order_and_a_repeated_stage_accumulates() {
        let mut t = StageTimes::new();
        t.add("read", 1.0);
        t.add("fit", 2.0);
        t.add("read", 0.5);
        let mut inner = StageTimes::new();
        inner.add("normals", 0.25);
        t.add_all("detect", &inner);
        let names: Vec<&str> = t.iter().map(|(s, _)| s).collect();
        assert_eq!(names, ["read", "fit", "detect.normals"]);
        assert_eq!(t.get("read"), Some(1.5));
        assert_eq!(t.get("missing"), None);
        assert_eq!(t.to_json()[2]["stage"], "detect.normals");
        assert_eq!(
            t.summary(),
            "read 1.500 s, fit 2.000 s, detect.normals 0.250 s"
        );
    }

    #[test]
    fn laps_measure_consecutive_intervals() {
        let outer = Instant::now();
        let mut w = Stopwatch::start();
        std::thread::sleep(std::time::Duration::from_millis(5));
        let a = w.lap("a");
        let b = w.lap("b");
        let total = outer.elapsed().as_secs_f64();
        assert!(a >= 0.005, "the sleep lies in the first lap: {a}");
        assert!(a + b <= total, "laps do not overlap: {a} + {b} > {total}");
        assert_eq!(w.times.iter().count(), 2);
    }
}
