//! The load generator behind `mvgrasp bench`: N concurrent callers send the
//! same frame for a duration or a count, optionally paced to a total rate,
//! over one connection or several (a fleet's robots each have their own).

use std::{
    sync::{
        Arc,
        atomic::{AtomicUsize, Ordering},
    },
    time::{Duration, Instant},
};

use indicatif::ProgressBar;

use crate::{PlannerClient, Result, pb};

/// How to load the server.
#[derive(Debug, Clone)]
pub struct BenchConfig {
    /// Callers with a call in flight at once.
    pub concurrency: usize,
    /// Stop after this long (measured part).
    pub duration: Option<Duration>,
    /// Stop after this many calls (measured part).
    pub count: Option<usize>,
    /// Total calls per second across callers (unpaced when unset).
    pub rate: Option<f64>,
    /// Calls before measuring starts (not counted), shared out over the
    /// connections (each gets its share rounded up: at least one).
    pub warmup: usize,
}

/// What a run measured. Latencies are client-side, end to end (ms).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct BenchReport {
    /// Callers.
    pub concurrency: usize,
    /// Successful calls.
    pub ok: usize,
    /// Failed calls.
    pub errors: usize,
    /// The first error seen, if any.
    pub first_error: Option<String>,
    /// Wall time of the measured part (s).
    pub elapsed_s: f64,
    /// Successful calls per second.
    pub throughput_per_s: f64,
    /// Latency percentiles (ms): 50, 90, 99, and the maximum.
    pub p50_ms: f64,
    /// 90th percentile (ms).
    pub p90_ms: f64,
    /// 99th percentile (ms).
    pub p99_ms: f64,
    /// Slowest call (ms).
    pub max_ms: f64,
    /// Median time inside the server (`timings.total_ms`).
    pub server_p50_ms: f64,
    /// Mean grasps per answer.
    pub mean_grasps: f64,
    /// Failed calls by gRPC code (`Connect` when no connection was made).
    pub errors_by_code: std::collections::BTreeMap<String, usize>,
    /// Time to the error of failed calls (ms): median, 99th percentile, slowest.
    pub error_p50_ms: f64,
    /// 99th percentile of failed calls (ms).
    pub error_p99_ms: f64,
    /// Slowest failed call (ms).
    pub error_max_ms: f64,
}

/// The `q`-quantile of sorted `values` (nearest rank).
pub fn quantile(sorted: &[f64], q: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let rank = (q * sorted.len() as f64).ceil() as usize;
    sorted[rank.clamp(1, sorted.len()) - 1]
}

#[derive(Default)]
struct Tally {
    latencies_ms: Vec<f64>,
    server_ms: Vec<f64>,
    grasps: usize,
    errors: usize,
    first_error: Option<String>,
    error_latencies_ms: Vec<f64>,
    errors_by_code: std::collections::BTreeMap<String, usize>,
}

fn code_of(e: &crate::Error) -> String {
    match e {
        crate::Error::Rpc(status) => format!("{:?}", status.code()),
        crate::Error::Connect { .. } => "Connect".to_owned(),
        crate::Error::Input { .. } => "Input".to_owned(),
    }
}

/// Runs the benchmark, caller `i` calling through `connections[i %
/// connections.len()]` (with none, nothing is called); `progress` (if any)
/// ticks once per measured call.
pub async fn run(
    connections: &[PlannerClient],
    request: &pb::PlanGraspsRequest,
    config: &BenchConfig,
    progress: Option<ProgressBar>,
) -> Result<BenchReport> {
    for connection in connections {
        let mut warm = connection.clone();
        for _ in 0..config.warmup.div_ceil(connections.len()) {
            // Unmeasured: a warm-up call that fails (a deadline shorter than a
            // plan, say) fails again, counted, in the measured part.
            let _ = warm.plan(request.clone()).await;
        }
    }
    let tickets = Arc::new(AtomicUsize::new(0));
    let start = Instant::now();
    let mut tasks = Vec::new();
    // Cycling over no connection gives no caller.
    for connection in connections.iter().cycle().take(config.concurrency.max(1)) {
        let (mut client, request, config) = (connection.clone(), request.clone(), config.clone());
        let (tickets, progress) = (Arc::clone(&tickets), progress.clone());
        tasks.push(tokio::spawn(async move {
            let mut tally = Tally::default();
            loop {
                let ticket = tickets.fetch_add(1, Ordering::SeqCst);
                if config.count.is_some_and(|n| ticket >= n)
                    || config.duration.is_some_and(|d| start.elapsed() >= d)
                {
                    break;
                }
                if let Some(rate) = config.rate {
                    tokio::time::sleep_until((start + Duration::from_secs_f64(ticket as f64 / rate)).into())
                        .await;
                }
                let sent = Instant::now();
                match client.plan(request.clone()).await {
                    Ok(answer) => {
                        tally.latencies_ms.push(sent.elapsed().as_secs_f64() * 1e3);
                        tally
                            .server_ms
                            .push(answer.timings.map_or(f64::NAN, |t| t.total_ms));
                        tally.grasps += answer.grasps.len();
                    }
                    Err(e) => {
                        tally.errors += 1;
                        tally.error_latencies_ms.push(sent.elapsed().as_secs_f64() * 1e3);
                        *tally.errors_by_code.entry(code_of(&e)).or_default() += 1;
                        tally.first_error.get_or_insert_with(|| e.to_string());
                    }
                }
                if let Some(bar) = &progress {
                    bar.inc(1);
                }
            }
            tally
        }));
    }
    let mut all = Tally::default();
    for task in tasks {
        let Ok(t) = task.await else { continue };
        all.latencies_ms.extend(t.latencies_ms);
        all.server_ms.extend(t.server_ms);
        all.grasps += t.grasps;
        all.errors += t.errors;
        all.error_latencies_ms.extend(t.error_latencies_ms);
        for (code, n) in t.errors_by_code {
            *all.errors_by_code.entry(code).or_default() += n;
        }
        if all.first_error.is_none() {
            all.first_error = t.first_error;
        }
    }
    let elapsed_s = start.elapsed().as_secs_f64();
    all.latencies_ms.sort_by(f64::total_cmp);
    all.server_ms.sort_by(f64::total_cmp);
    all.error_latencies_ms.sort_by(f64::total_cmp);
    let ok = all.latencies_ms.len();
    Ok(BenchReport {
        concurrency: config.concurrency.max(1),
        ok,
        errors: all.errors,
        first_error: all.first_error,
        elapsed_s,
        throughput_per_s: ok as f64 / elapsed_s.max(1e-9),
        p50_ms: quantile(&all.latencies_ms, 0.5),
        p90_ms: quantile(&all.latencies_ms, 0.9),
        p99_ms: quantile(&all.latencies_ms, 0.99),
        max_ms: all.latencies_ms.last().copied().unwrap_or(f64::NAN),
        server_p50_ms: quantile(&all.server_ms, 0.5),
        mean_grasps: all.grasps as f64 / ok.max(1) as f64,
        error_p50_ms: quantile(&all.error_latencies_ms, 0.5),
        error_p99_ms: quantile(&all.error_latencies_ms, 0.99),
        error_max_ms: all.error_latencies_ms.last().copied().unwrap_or(f64::NAN),
        errors_by_code: all.errors_by_code,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rank_quantiles() {
        let v: Vec<f64> = (1..=100).map(f64::from).collect();
        assert_eq!(quantile(&v, 0.5), 50.0);
        assert_eq!(quantile(&v, 0.99), 99.0);
        assert_eq!(quantile(&v, 1.0), 100.0);
        assert_eq!(quantile(&[3.0], 0.5), 3.0);
        assert!(quantile(&[], 0.5).is_nan());
    }
}
