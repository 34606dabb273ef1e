//! `mvgrasp-sim`: the synthetic data engine. Procedural objects
//! ([`objects`]), scenes laid out per scenario and seed ([`scene`]), and a
//! simulated depth camera with a consumer camera's noise ([`camera`]);
//! frames are written in the files the planner's tools read ([`files`]).
//!
//! ```
//! use mvgrasp_core::rng::SplitMix64;
//! use mvgrasp_sim::{camera::{Camera, render}, objects::Family, scene::{Scene, Scenario}};
//! let scene = Scene::generate(Scenario::Isolated, 1, &Family::ALL)?;
//! let target = nalgebra::Vector3::new(0.0, 0.0, f64::from(scene.table_z));
//! let camera = Camera::random(&mut SplitMix64::new(1), target, false);
//! let frame = render(&scene, &camera, None);
//! assert!(frame.labels.contains(&2)); // the object is in view
//! # Ok::<(), mvgrasp_sim::Error>(())
//! ```
//!
//! Grasp labels ([`grasp`]), training targets ([`targets`]) and the dataset
//! writer ([`dataset`]) make the training data; a rapier3d gripper
//! ([`physics`]) confirms grasps and settles piles ([`pile`]), and [`eval`]
//! runs the clear-the-table benchmark with a planner in the loop. User
//! meshes (OBJ, STL) join scenes through [`mesh`] and
//! [`objects::Catalog`].

pub mod camera;
pub mod dataset;
mod error;
pub mod eval;
pub mod files;
pub mod grasp;
pub mod mesh;
pub mod objects;
pub mod overlap;
pub mod physics;
pub mod pile;
pub mod scene;
pub mod targets;

pub use error::{Error, Result};
