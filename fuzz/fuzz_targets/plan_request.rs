//! Arbitrary bytes as a `PlanGraspsRequest`: decode, the server's conversion
//! and checks, planning with the analytic backend, and the response.

#![no_main]

use std::sync::OnceLock;

use libfuzzer_sys::fuzz_target;
use mvgrasp_core::{GraspNet, MomentsNet, Planner, PlannerConfig};
use mvgrasp_proto::v1::PlanGraspsRequest;
use mvgrasp_server::{
    convert,
    settings::{Limits, RequestDefaults},
};
use prost::Message;

fn planner() -> &'static Planner {
    static PLANNER: OnceLock<Planner> = OnceLock::new();
    PLANNER.get_or_init(|| {
        Planner::new(PlannerConfig::default(), MomentsNet::default().contract().clone())
            .unwrap_or_else(|e| panic!("planner: {e}"))
    })
}

fuzz_target!(|data: &[u8]| {
    let Ok(request) = PlanGraspsRequest::decode(data) else {
        return;
    };
    let Ok(scene) = convert::scene_of(&request, &Limits::default()) else {
        return;
    };
    let Ok(options) = convert::options_of(&request, &RequestDefaults::default()) else {
        return;
    };
    let mut net = MomentsNet::default();
    if let Ok(plan) = planner().plan(&scene, &options, &mut net) {
        let response = convert::response_of(&plan, "fuzz", &request.request_id, 0.0);
        for g in &response.grasps {
            assert!(g.quality.is_finite() && g.width_m.is_finite(), "{g:?}");
        }
        let _ = response.encode_to_vec();
    }
});
