//! `mvgrasp-server`: the stateless gRPC grasp-planning service.
//!
//! A call is validated and converted at the edge ([`convert`]), its CPU
//! stages run `mvgrasp-core` on tokio's blocking pool, and its views join
//! other calls' views in one network call ([`batcher`]). Metrics are
//! Prometheus text on their own port ([`metrics`]); settings come in layers
//! ([`settings`]).
//!
//! ```no_run
//! # async fn demo() -> Result<(), mvgrasp_server::Error> {
//! use mvgrasp_server::{BackendKind, Settings};
//! let mut settings = Settings::default();
//! settings.listen = "127.0.0.1:0".parse().unwrap();
//! settings.model.backend = BackendKind::Baseline;
//! let server = mvgrasp_server::start(settings).await?;
//! println!("planning on {}", server.addr);
//! server.shutdown().await?;
//! # Ok(()) }
//! ```

pub mod admission;
pub mod backend;
pub mod batcher;
pub mod convert;
mod error;
pub mod metrics;
pub mod security;
mod server;
mod service;
pub mod settings;

pub use error::{Error, Result};
pub use server::{RunningServer, start, start_with_net, termination};
pub use service::{PlannerService, PlannerState};
pub use settings::{BackendKind, Device, Overrides, Settings};

/// The binary's entry point: settings from flags/env/file, serve until SIGTERM.
pub async fn run(overrides: Overrides) -> Result<()> {
    let settings = Settings::load(&overrides)?;
    let server = start(settings).await?;
    termination().await;
    server.shutdown().await
}
