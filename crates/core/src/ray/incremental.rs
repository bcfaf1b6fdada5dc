//! Incremental scene evaluation (thesis Algorithm 3): after flipping a few candidates,
//! only the rays they cross are re-evaluated.
//!
//! [`SceneState`] keeps the existence vector, every ray's current log-likelihood and
//! their total. [`SceneState::propose`] flips a set of candidates, recomputes the touched
//! rays into a scratch list and returns the change of `log p(D | Φ)`; the caller then
//! [`accept`](SceneState::accept)s (the scratch values are committed) or
//! [`reject`](SceneState::reject)s (the flips are undone). A step costs
//! O(Σ crossings of the touched rays), independent of the cloud size.

use super::raytree::RayTable;
use crate::{Error, Result};

/// A scene Φ with cached per-ray log-likelihoods over a [`RayTable`].
#[derive(Debug, Clone)]
pub struct SceneState<'t> {
    table: &'t RayTable,
    exists: Vec<bool>,
    ray_ll: Vec<f64>,
    total: f64,
    /// Epoch stamp per ray, to visit each touched ray once per proposal.
    stamp: Vec<u32>,
    epoch: u32,
    /// Touched rays and their proposed log-likelihoods.
    pending: Vec<(u32, f64)>,
    pending_flips: Vec<u32>,
    pending_delta: f64,
}

impl<'t> SceneState<'t> {
    /// The scene `exists` (length N) with a full evaluation (Algorithm 2).
    pub fn new(table: &'t RayTable, exists: Vec<bool>) -> Result<Self> {
        let ray_ll = table.ray_log_likelihoods(&exists)?;
        let total = ray_ll.iter().sum();
        Ok(SceneState {
            table,
            exists,
            stamp: vec![0; ray_ll.len()],
            ray_ll,
            total,
            epoch: 0,
            pending: Vec::new(),
            pending_flips: Vec::new(),
            pending_delta: 0.0,
        })
    }

    /// The current existence vector.
    pub fn exists(&self) -> &[bool] {
        &self.exists
    }

    /// `log p(D | Φ)` of the current scene (nats), kept up to date by accepted steps.
    pub fn log_likelihood(&self) -> f64 {
        self.total
    }

    /// The cached log-likelihood of every ray (nats).
    pub fn ray_log_likelihoods(&self) -> &[f64] {
        &self.ray_ll
    }

    /// Re-sums the cached per-ray values (drops the rounding drift of many steps).
    pub fn resum(&mut self) {
        self.total = self.ray_ll.iter().sum();
    }

    /// Flips the candidates `flips` (all `< N`; an id listed twice flips back) and returns the change
    /// of `log p(D | Φ)` (nats). Must be followed by [`SceneState::accept`] or
    /// [`SceneState::reject`] before the next proposal.
    pub fn propose(&mut self, flips: &[u32]) -> Result<f64> {
        if !self.pending_flips.is_empty() {
            return Err(Error::invalid(
                "a proposal is pending: accept or reject it first",
            ));
        }
        if let Some(k) = flips.iter().position(|&i| i as usize >= self.exists.len()) {
            return Err(Error::IndexOutOfRange {
                what: format!("flips[{k}]"),
                index: flips[k] as usize,
                item: "candidate",
                count: self.exists.len(),
            });
        }
        self.next_epoch();
        for &i in flips {
            let e = &mut self.exists[i as usize];
            *e = !*e;
        }
        self.pending_flips.extend_from_slice(flips);
        let mut delta = 0.0;
        for &i in flips {
            for &j in self.table.candidate_rays(i as usize) {
                if self.stamp[j as usize] == self.epoch {
                    continue;
                }
                self.stamp[j as usize] = self.epoch;
                let new = self.table.ray_log_likelihood(j as usize, &self.exists);
                delta += new - self.ray_ll[j as usize];
                self.pending.push((j, new));
            }
        }
        self.pending_delta = delta;
        Ok(delta)
    }

    /// Keeps the pending proposal.
    pub fn accept(&mut self) {
        for &(j, v) in &self.pending {
            self.ray_ll[j as usize] = v;
        }
        self.total += self.pending_delta;
        self.clear_pending();
    }

    /// Undoes the pending proposal.
    pub fn reject(&mut self) {
        for &i in &self.pending_flips {
            let e = &mut self.exists[i as usize];
            *e = !*e;
        }
        self.clear_pending();
    }

    /// `propose` then `accept`: flips `flips` and returns the change (nats).
    pub fn flip(&mut self, flips: &[u32]) -> Result<f64> {
        let d = self.propose(flips)?;
        self.accept();
        Ok(d)
    }

    fn clear_pending(&mut self) {
        self.pending.clear();
        self.pending_flips.clear();
        self.pending_delta = 0.0;
    }

    fn next_epoch(&mut self) {
        if self.epoch == u32::MAX {
            self.stamp.fill(0);
            self.epoch = 0;
        }
        self.epoch += 1;
    }
}
