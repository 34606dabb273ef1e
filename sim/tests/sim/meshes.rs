//! Mesh objects (`sim::mesh`): the sample meshes load with their volumes
//! and make every scenario; a catalog without meshes draws what it always drew.

use std::path::PathBuf;

use mvgrasp_sim::mesh::load_meshes;

use super::*;

/// The sample meshes (`samples/meshes/make_meshes.py`).
fn sample_meshes() -> Vec<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../samples/meshes");
    ["u_channel.obj", "plus_prism.obj", "hex_nut.stl", "wedge.stl"]
        .iter()
        .map(|f| dir.join(f))
        .collect()
}

#[test]
fn the_sample_meshes_load_with_their_volumes_and_make_every_scenario() {
    let meshes = load_meshes(&sample_meshes(), 1.0).unwrap();
    // Solid volumes from the drawings (m^3); the convex parts may bulge a little.
    let expected = [
        ("u_channel", 3.52e-4),
        ("plus_prism", 4.0e-4),
        ("hex_nut", 1.40e-4),
        ("wedge", 1.44e-4),
    ];
    for (m, (name, volume)) in meshes.iter().zip(expected) {
        assert_eq!(m.name, name);
        assert_eq!(m.family, Family::Mesh);
        let v: f32 = m.parts.iter().map(|(_, s)| s.mass_properties(1.0).mass()).sum();
        assert!(
            (v - volume).abs() < 0.2 * volume,
            "{name}: {v:.3e} m^3 in {} parts, drawn {volume:.3e}",
            m.parts.len()
        );
        assert!(
            (m.aabb.mins.z).abs() < 1e-4,
            "{name}: the origin is at the bottom"
        );
    }
    // The hole of the nut needs several convex parts around it.
    assert!(
        meshes[2].parts.len() >= 4,
        "hex_nut: {} parts",
        meshes[2].parts.len()
    );
    let catalog = Catalog {
        families: Vec::new(),
        meshes,
    };
    for scenario in Scenario::ALL {
        let scene = Scene::generate_from(scenario, 3, &catalog).unwrap();
        assert!(scene.objects.iter().all(|o| o.model.family == Family::Mesh));
        let camera = Camera::random(
            &mut SplitMix64::new(3),
            Vector3::new(0.0, 0.0, f64::from(scene.table_z)),
            true,
        );
        let frame = render(&scene, &camera, None);
        let seen = (0..scene.objects.len())
            .filter(|&i| frame.labels.contains(&(2 + i as u16)))
            .count();
        assert!(
            2 * seen >= scene.objects.len(),
            "{}: {seen} of {} mesh objects in view",
            scenario.name(),
            scene.objects.len()
        );
    }
}

#[test]
fn a_catalog_without_meshes_draws_the_scenes_it_always_drew() {
    let before = Scene::generate(Scenario::Packed, 21, &Family::ALL).unwrap();
    let after = Scene::generate_from(Scenario::Packed, 21, &Catalog::of(&Family::ALL)).unwrap();
    let poses = |s: &Scene| -> Vec<[f32; 3]> {
        s.objects
            .iter()
            .map(|o| o.world_from_object.translation.to_array())
            .collect()
    };
    assert_eq!(poses(&before), poses(&after));
    let err = Scene::generate_from(Scenario::Packed, 21, &Catalog::default()).unwrap_err();
    assert!(err.to_string().contains("families"), "{err}");
}
