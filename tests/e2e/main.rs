//! End-to-end tests: the server started in-process on ephemeral ports, the
//! client library calling it over real gRPC, on ray-cast frames.

#![allow(clippy::unwrap_used, clippy::expect_used, missing_docs)]

#[path = "../../core/tests/pipeline/scene.rs"]
#[allow(dead_code, clippy::all, missing_docs)]
mod scene;

mod bad_input;
mod clear_table;
mod contract;
mod fixture;
mod onnx;
mod operations;
mod security;
