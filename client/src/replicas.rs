//! Several planner replicas behind one client: calls go round robin, a
//! replica that answered UNAVAILABLE sits out a growing back-off, and such a
//! call is sent on to the other replicas in turn, each once.
//!
//! HTTP/2 keeps a client on one connection, so a plain channel to a
//! Kubernetes Service would send all of a robot's calls to one pod; this is
//! the client-side balancing the fleet deployment relies on
//! (`deploy/k8s/`'s headless Service).

use std::{
    net::SocketAddr,
    sync::atomic::{AtomicU32, AtomicU64, AtomicUsize, Ordering},
    time::{Duration, Instant},
};

use crate::{Error, Result};

/// First sit-out after an UNAVAILABLE; doubles with each one in a row.
const FIRST_BACKOFF: Duration = Duration::from_millis(250);
/// Longest sit-out: a replica that came back is tried again this soon.
const MAX_BACKOFF: Duration = Duration::from_secs(5);

/// One replica's state, shared by every clone of the client.
#[derive(Debug)]
pub(crate) struct Health {
    failures_in_row: AtomicU32,
    /// Milliseconds after the pool's epoch until which it sits out.
    down_until_ms: AtomicU64,
    answered: AtomicU64,
    failed: AtomicU64,
}

impl Health {
    fn new() -> Self {
        Self {
            failures_in_row: AtomicU32::new(0),
            down_until_ms: AtomicU64::new(0),
            answered: AtomicU64::new(0),
            failed: AtomicU64::new(0),
        }
    }
}

/// What one replica has done so far (for logs and tests).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ReplicaStats {
    /// Its address.
    pub endpoint: String,
    /// Calls it answered (any status but UNAVAILABLE).
    pub answered: u64,
    /// Calls that failed on it with UNAVAILABLE or a broken connection
    /// (each sent on to another replica while one was left untried).
    pub unavailable: u64,
    /// Whether it is sitting out now.
    pub down: bool,
}

/// Round-robin choice over replicas with a back-off for failed ones.
#[derive(Debug)]
pub(crate) struct RoundRobin {
    health: Vec<Health>,
    next: AtomicUsize,
    epoch: Instant,
    retries: AtomicU64,
}

impl RoundRobin {
    /// `n` replicas, all up; `down` lists those that start sitting out
    /// (they failed to connect).
    pub(crate) fn new(n: usize, down: &[usize]) -> Self {
        let rr = Self {
            health: (0..n).map(|_| Health::new()).collect(),
            next: AtomicUsize::new(0),
            epoch: Instant::now(),
            retries: AtomicU64::new(0),
        };
        let now = rr.epoch;
        for &i in down {
            rr.mark_unavailable_at(i, now);
        }
        rr
    }

    pub(crate) fn len(&self) -> usize {
        self.health.len()
    }

    fn millis(&self, at: Instant) -> u64 {
        at.saturating_duration_since(self.epoch).as_millis() as u64
    }

    fn is_down_at(&self, i: usize, at: Instant) -> bool {
        self.health[i].down_until_ms.load(Ordering::Relaxed) > self.millis(at)
    }

    /// The next replica in turn that is not sitting out. When every one
    /// sits out, the one due back first (a call is better tried than
    /// refused here).
    pub(crate) fn pick_at(&self, at: Instant) -> usize {
        let n = self.len();
        let mut fallback: Option<(u64, usize)> = None;
        for _ in 0..n {
            let i = self.next.fetch_add(1, Ordering::Relaxed) % n;
            if !self.is_down_at(i, at) {
                return i;
            }
            let due = self.health[i].down_until_ms.load(Ordering::Relaxed);
            if fallback.is_none_or(|(best, _)| due < best) {
                fallback = Some((due, i));
            }
        }
        // Start the next pick one further on, so that replicas due back
        // together take turns.
        self.next.fetch_add(1, Ordering::Relaxed);
        fallback.map_or(0, |(_, i)| i)
    }

    pub(crate) fn pick(&self) -> usize {
        self.pick_at(Instant::now())
    }

    /// Where a retry goes: among the replicas not `tried` yet for this call,
    /// the next in turn that has not failed since its last answer, else one
    /// not sitting out, else the one due back first; `None` when all were
    /// tried. A replica back from its sit-out is probed by first attempts,
    /// not by retries.
    pub(crate) fn pick_untried_at(&self, tried: &[bool], at: Instant) -> Option<usize> {
        let n = self.len();
        let start = self.next.fetch_add(1, Ordering::Relaxed);
        let order = (0..n).map(|k| (start + k) % n).filter(|&i| !tried[i]);
        let rank = |i: usize| {
            let h = &self.health[i];
            (
                self.is_down_at(i, at),
                h.failures_in_row.load(Ordering::Relaxed) > 0,
                h.down_until_ms.load(Ordering::Relaxed),
            )
        };
        // min_by_key keeps the first of equals: turn order breaks ties.
        order.min_by_key(|&i| rank(i))
    }

    pub(crate) fn pick_untried(&self, tried: &[bool]) -> Option<usize> {
        self.pick_untried_at(tried, Instant::now())
    }

    /// Replica `i` answered: it is up, its back-off starts over.
    pub(crate) fn mark_answered(&self, i: usize) {
        let h = &self.health[i];
        h.answered.fetch_add(1, Ordering::Relaxed);
        h.failures_in_row.store(0, Ordering::Relaxed);
        h.down_until_ms.store(0, Ordering::Relaxed);
    }

    /// Replica `i` was unavailable at `at`: it sits out 250 ms, doubling
    /// with each failure in a row up to 5 s.
    pub(crate) fn mark_unavailable_at(&self, i: usize, at: Instant) {
        let h = &self.health[i];
        h.failed.fetch_add(1, Ordering::Relaxed);
        let in_row = h.failures_in_row.fetch_add(1, Ordering::Relaxed).min(16);
        let backoff = FIRST_BACKOFF.saturating_mul(1 << in_row).min(MAX_BACKOFF);
        h.down_until_ms
            .store(self.millis(at + backoff), Ordering::Relaxed);
    }

    pub(crate) fn mark_unavailable(&self, i: usize) {
        self.mark_unavailable_at(i, Instant::now());
    }

    pub(crate) fn count_retry(&self) {
        self.retries.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn retries(&self) -> u64 {
        self.retries.load(Ordering::Relaxed)
    }

    pub(crate) fn stats(&self, endpoints: &[String]) -> Vec<ReplicaStats> {
        let now = Instant::now();
        endpoints
            .iter()
            .zip(&self.health)
            .enumerate()
            .map(|(i, (endpoint, h))| ReplicaStats {
                endpoint: endpoint.clone(),
                answered: h.answered.load(Ordering::Relaxed),
                unavailable: h.failed.load(Ordering::Relaxed),
                down: self.is_down_at(i, now),
            })
            .collect()
    }
}

/// The endpoints `spec` names: one address (`http://host:port`), several
/// separated by commas, or `dns:///host:port` for every address the name
/// resolves to (resolved now, once: a Kubernetes headless Service lists one
/// record per ready pod).
pub async fn endpoints(spec: &str) -> Result<Vec<String>> {
    let mut out = Vec::new();
    for part in spec.split(',').map(str::trim).filter(|p| !p.is_empty()) {
        let Some(name) = part.strip_prefix("dns:///").or_else(|| part.strip_prefix("dns:")) else {
            out.push(part.to_owned());
            continue;
        };
        let error = |reason: String| Error::Connect {
            endpoint: part.to_owned(),
            reason,
        };
        if name
            .rsplit_once(':')
            .is_none_or(|(_, port)| port.parse::<u16>().is_err())
        {
            return Err(error("give dns:///host:port".to_owned()));
        }
        let mut addrs: Vec<SocketAddr> = tokio::net::lookup_host(name)
            .await
            .map_err(|e| error(format!("resolving {name}: {e}")))?
            .collect();
        addrs.sort();
        addrs.dedup();
        if addrs.is_empty() {
            return Err(error(format!("{name} resolves to no address")));
        }
        out.extend(addrs.into_iter().map(|a| format!("http://{a}")));
    }
    if out.is_empty() {
        return Err(Error::Connect {
            endpoint: spec.to_owned(),
            reason: "no address given".to_owned(),
        });
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn calls_go_round_robin() {
        let rr = RoundRobin::new(3, &[]);
        let now = Instant::now();
        let picks: Vec<usize> = (0..6).map(|_| rr.pick_at(now)).collect();
        assert_eq!(picks, [0, 1, 2, 0, 1, 2]);
    }

    #[test]
    fn retries_go_to_replicas_not_tried_preferring_healthy_ones() {
        let rr = RoundRobin::new(3, &[]);
        let t0 = Instant::now();
        for first in 0..3 {
            let mut tried = [false; 3];
            tried[first] = true;
            let second = rr.pick_untried_at(&tried, t0).unwrap();
            assert_ne!(second, first);
            tried[second] = true;
            let third = rr.pick_untried_at(&tried, t0).unwrap();
            assert!(third != first && third != second);
            tried[third] = true;
            assert_eq!(rr.pick_untried_at(&tried, t0), None, "each replica once per call");
        }
        // Replica 1 failed a second ago and is back from its sit-out, but a
        // retry goes to replica 2, which has not failed.
        rr.mark_unavailable_at(1, t0);
        let later = t0 + Duration::from_secs(1);
        for _ in 0..4 {
            assert_eq!(rr.pick_untried_at(&[true, false, false], later), Some(2));
        }
        // With no other left, it goes to replica 1 after all.
        assert_eq!(rr.pick_untried_at(&[true, false, true], later), Some(1));
        assert_eq!(RoundRobin::new(1, &[]).pick_untried_at(&[true], later), None);
    }

    #[test]
    fn an_unavailable_replica_sits_out_a_growing_backoff() {
        let rr = RoundRobin::new(3, &[]);
        let t0 = Instant::now();
        rr.mark_unavailable_at(1, t0);
        let picks: Vec<usize> = (0..4).map(|_| rr.pick_at(t0)).collect();
        assert_eq!(picks, [0, 2, 0, 2], "replica 1 sits out");
        // Back after 250 ms.
        let later = t0 + Duration::from_millis(300);
        assert!((0..3).map(|_| rr.pick_at(later)).any(|i| i == 1));
        // A second failure in a row: 500 ms.
        rr.mark_unavailable_at(1, later);
        assert!(rr.is_down_at(1, later + Duration::from_millis(400)));
        assert!(!rr.is_down_at(1, later + Duration::from_millis(600)));
        // An answer resets it.
        rr.mark_answered(1);
        assert!(!rr.is_down_at(1, later));
        rr.mark_unavailable_at(1, later);
        assert!(!rr.is_down_at(1, later + Duration::from_millis(300)));
        // Never longer than 5 s.
        for _ in 0..40 {
            rr.mark_unavailable_at(2, t0);
        }
        assert!(rr.is_down_at(2, t0 + Duration::from_millis(4_900)));
        assert!(!rr.is_down_at(2, t0 + Duration::from_millis(5_100)));
    }

    #[test]
    fn when_all_sit_out_calls_are_still_tried() {
        let rr = RoundRobin::new(2, &[0, 1]);
        let now = Instant::now();
        let picks: Vec<usize> = (0..4).map(|_| rr.pick_at(now)).collect();
        assert!(picks.contains(&0) && picks.contains(&1), "{picks:?}");
        let stats = rr.stats(&["a".into(), "b".into()]);
        assert!(stats.iter().all(|s| s.down && s.unavailable == 1), "{stats:?}");
    }

    #[tokio::test]
    async fn endpoint_lists_and_dns_names() {
        assert_eq!(
            endpoints("http://a:1, http://b:2,").await.unwrap(),
            ["http://a:1", "http://b:2"]
        );
        assert_eq!(
            endpoints("dns:///127.0.0.1:50051").await.unwrap(),
            ["http://127.0.0.1:50051"]
        );
        assert_eq!(
            endpoints("dns:localhost:7,http://c:3")
                .await
                .unwrap()
                .last()
                .unwrap(),
            "http://c:3"
        );
        assert!(endpoints("dns:///localhost").await.is_err(), "a port is needed");
        assert!(endpoints(" , ").await.is_err());
    }
}
