//! Compiles `mvgrasp/v1/*.proto` with protox (pure Rust, no protoc) and
//! writes the descriptor set that server reflection serves.

use std::{env, fs, path::PathBuf};

use prost::Message;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let proto = "mvgrasp/v1/grasp_planner.proto";
    println!("cargo:rerun-if-changed={proto}");
    let descriptors = protox::compile([proto], ["."])?;
    let out_dir = PathBuf::from(env::var("OUT_DIR")?);
    fs::write(
        out_dir.join("mvgrasp_descriptor.bin"),
        descriptors.encode_to_vec(),
    )?;
    tonic_prost_build::configure()
        // A frame's or cloud's bytes are shared, not copied: decoded as a
        // view of the received message, cloned by reference count.
        .bytes(".mvgrasp.v1.DepthImage.data")
        .bytes(".mvgrasp.v1.PointCloud.xyz")
        .build_client(true)
        .build_server(true)
        .compile_fds(descriptors)?;
    Ok(())
}
