//! `sim`: the synthetic data engine's command line.

use std::path::PathBuf;

use anyhow::Context;
use clap::{Parser, Subcommand};
use mvgrasp_core::rng::SplitMix64;
use mvgrasp_sim::{
    camera::{Camera, NoiseModel, render},
    files::write_frame,
    objects::Family,
    scene::{Scenario, Scene},
};
use nalgebra::Vector3;

/// Synthetic scenes and a simulated depth camera for mvgrasp.
#[derive(Debug, Parser)]
#[command(version, about)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Render one scene: depth.png + camera.json (what `mvgrasp plan` reads),
    /// labels.png and preview.png.
    RenderSample {
        /// isolated, packed or clutter.
        #[arg(long, default_value = "packed")]
        scenario: String,
        /// Scene and camera seed.
        #[arg(long, default_value_t = 0)]
        seed: u64,
        /// Output folder.
        #[arg(long)]
        out: PathBuf,
        /// Shape families to draw from (comma-separated; default all).
        #[arg(long, value_delimiter = ',')]
        families: Vec<String>,
        /// Look straight down instead of from 30-60 degrees elevation.
        #[arg(long)]
        top_down: bool,
        /// A perfect sensor (no noise, no dropouts).
        #[arg(long)]
        no_noise: bool,
    },
}

fn main() -> anyhow::Result<()> {
    match Cli::parse().command {
        Command::RenderSample {
            scenario,
            seed,
            out,
            families,
            top_down,
            no_noise,
        } => {
            let scenario = Scenario::parse(&scenario)
                .with_context(|| format!("--scenario {scenario:?}: isolated, packed or clutter"))?;
            let families: Vec<Family> = if families.is_empty() {
                Family::ALL.to_vec()
            } else {
                families
                    .iter()
                    .map(|f| Family::parse(f).with_context(|| format!("--families: unknown family {f:?}")))
                    .collect::<anyhow::Result<_>>()?
            };
            let scene = Scene::generate(scenario, seed, &families)?;
            let mut rng = SplitMix64::new(seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) ^ 0xCA3E);
            let target = Vector3::new(0.0, 0.0, f64::from(scene.table_z));
            let camera = Camera::random(&mut rng, target, top_down);
            let noise = NoiseModel::default();
            let frame = render(&scene, &camera, (!no_noise).then_some((&noise, &mut rng)));
            write_frame(&out, &scene, &frame)?;
            println!(
                "{} seed {seed}: {} objects ({}), table at {:.3} m; wrote {}/{{depth.png, labels.png, camera.json, preview.png}}",
                scenario.name(),
                scene.objects.len(),
                scene
                    .objects
                    .iter()
                    .map(|o| o.model.family.name())
                    .collect::<Vec<_>>()
                    .join(", "),
                scene.table_z,
                out.display()
            );
        }
    }
    Ok(())
}
