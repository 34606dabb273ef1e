//! `mvgrasp-server`: serves grasp plans over gRPC until SIGTERM.

use clap::Parser;
use tracing_subscriber::EnvFilter;

/// The mvgrasp grasp-planning service.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(flatten)]
    overrides: mvgrasp_server::Overrides,
}

#[tokio::main]
async fn main() -> anyhow::Result<()> {
    tracing_subscriber::fmt()
        .with_env_filter(EnvFilter::try_from_env("MVGRASP_LOG").unwrap_or_else(|_| EnvFilter::new("info")))
        .init();
    let cli = Cli::parse();
    mvgrasp_server::run(cli.overrides).await?;
    Ok(())
}
