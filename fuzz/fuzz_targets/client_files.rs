//! Arbitrary bytes through the client's file readers: PLY, PCD, the depth
//! PNG and the camera JSON.

#![no_main]

use libfuzzer_sys::fuzz_target;
use mvgrasp_client::{cloud, scene};

fuzz_target!(|data: &[u8]| {
    let _ = cloud::parse_ply(data);
    let _ = cloud::parse_pcd(data);
    if let Ok((width, height, mm)) = scene::decode_depth_png(data) {
        assert_eq!(mm.len() as u64, u64::from(width) * u64::from(height));
    }
    if let Ok(text) = std::str::from_utf8(data) {
        let _ = scene::check_camera_json(text, "fuzz.json".as_ref());
    }
});
