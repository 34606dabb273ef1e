//! Arbitrary bytes as what the robot sends the bridge: RTDE packets and the
//! state in a data package, and the gripper's answers.

#![no_main]

use libfuzzer_sys::fuzz_target;
use robot_bridge::{gripper, rtde};

fuzz_target!(|data: &[u8]| {
    let mut stream = data;
    while let Ok((kind, payload)) = rtde::read_packet(&mut stream) {
        if let Some(recipe) = payload.first() {
            let _ = rtde::RobotState::from_packet(kind, &payload, *recipe);
        }
    }
    if let Ok(text) = std::str::from_utf8(data) {
        for var in ["OBJ", "POS", "STA"] {
            let _ = gripper::parse_get_reply(text, var);
        }
    }
});
