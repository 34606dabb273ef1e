//! The bridge's kinematics and pick planning as a line protocol: one JSON
//! request per line in, one JSON answer per line out
//! (`robot-bridge plan-jsonl --config FILE`).
//!
//! This is how a simulator drives the bridge exactly as a cell would: the
//! physics referee (`referee/`) sends each attempt's ranked grasps and the
//! detected objects, and runs the answered joint waypoints on its simulated
//! arm. Requests:
//!
//! - `{"fk": [q1..q6]}` -> `{"ok": true, "position": [x, y, z], "orientation": [x, y, z, w]}`,
//!   `base_from_flange`;
//! - `{"arm_reach": null}` -> `{"ok": true, "arm_reach": {"shoulder", "axis",
//!   "wrist_back_m", "approach_m", "max_m", "min_axis_m"}}`, where the arm
//!   reaches as the planner's `ArmReach` takes it (`PickConfig::arm_reach`),
//!   for a simulator that calls the planner itself;
//! - `{"robot_body": [q1..q6]}` -> `{"ok": true, "robot_body": [{"a", "b",
//!   "radius_m"}]}`, the arm at those joints as the planner's
//!   `PlanGraspsRequest.robot_body` takes it (`PickConfig::robot_body`), so
//!   a simulator asks the planner as `pick` does;
//! - `{"plan": {"grasps": [...], "scene": {...}, "current": [q1..q6], "released": n}}`
//!   -> `{"ok": true, "grasp_index": k, "steps": [...], "refused": [...]}`. Each
//!   grasp is `{"position", "orientation", "width_m", "quality", "object"}` in
//!   the world (mvgrasp grasp frame); the optional `scene` is the planner's
//!   answer, `{"detected": [{"id", "position", "orientation", "extent_min_m",
//!   "extent_max_m"}], "table_plane": {"normal", "offset_m"}, "workspace":
//!   {"min", "max"}, "obstacles": [{"min", "max"}], "robot_body_left_out"}`
//!   (`obstacles`, optional: the planner's boxes outside the workspace;
//!   `robot_body_left_out`, default false: the planner was asked with the
//!   robot's body), turned into obstacles exactly as `pick` turns a
//!   planner's answer into them (`obstacles_left_out` in the answer: the
//!   boxes taken for the cell; `obstacles_cut`: those against the arm
//!   where it stands or over the basket and beside it, kept cut back
//!   clear of them). A `movel` step carries its joint
//!   samples every centimetre (`path`), so the straight line is the one the
//!   bridge checked. `refused` says, for each better-ranked grasp that was
//!   skipped, why. The optional `released` (default 0) counts the objects
//!   let go over the basket since it was emptied, which chooses where over
//!   it this one goes (`PickConfig::release_spot`);
//! - `{"order": {"grasps": [{"position", "orientation"}], "failed": [...]}}`
//!   -> `{"ok": true, "order": [k...]}`, the order to try ranked grasps in
//!   once the picks at the `failed` poses came up empty
//!   (`PickConfig::order_after_failures`): a caller that keeps a scene's
//!   failed picks asks this before `plan`.
//!
//! Any error is an answer `{"ok": false, "error": "..."}`; the loop goes on.

use std::io::{BufRead, Write};

use mvgrasp_core::Workspace;
use nalgebra::{Isometry3, Vector3};
use serde::Deserialize;

use crate::collision::BoxObstacle;
use crate::error::{Error, Result};
use crate::pick::{GraspTarget, PickConfig, PoseJson, SeenObstacles, plan_pick};
use crate::planner::{ObjectBox, obstacles, outside_box};
use crate::ur5e::{Joints, Ur5e};

/// One request line.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
enum Request {
    /// Forward kinematics.
    #[serde(rename = "fk")]
    Fk(Joints),
    /// Where the arm reaches, for the planner.
    #[serde(rename = "arm_reach")]
    ArmReach(()),
    /// The robot's body at these joints, for the planner.
    #[serde(rename = "robot_body")]
    RobotBody(Joints),
    /// A pick for ranked grasps.
    #[serde(rename = "plan")]
    Plan(PlanRequest),
    /// The order to try grasps in after failed picks.
    #[serde(rename = "order")]
    Order(OrderRequest),
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OrderRequest {
    grasps: Vec<PoseJson>,
    failed: Vec<PoseJson>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlanRequest {
    grasps: Vec<GraspJson>,
    scene: Option<SceneJson>,
    current: Joints,
    /// Objects let go over the basket since it was emptied (`PickConfig::released`).
    #[serde(default)]
    released: usize,
}

/// The planner's answer as obstacles come from it: the detected objects,
/// the table plane and the request's workspace (`planner::obstacles`).
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneJson {
    detected: Vec<DetectedJson>,
    table_plane: PlaneJson,
    workspace: WorkspaceJson,
    /// The planner's boxes of what stands outside the workspace
    /// (`PlanGraspsResponse.obstacles`); absent: none.
    #[serde(default)]
    obstacles: Vec<OutsideJson>,
    /// Whether the planner was asked with the robot's body where it stands
    /// (`robot_body`) and left its points out: a box the arm touches there
    /// is then kept, cut back clear of the arm ([`PickConfig::add_seen_obstacles`]).
    #[serde(default)]
    robot_body_left_out: bool,
}

/// A box seen outside the workspace: its corners, and the index in
/// `detected` of the object it continues past the border, if any.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct OutsideJson {
    min: [f64; 3],
    max: [f64; 3],
    #[serde(default)]
    object: Option<usize>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DetectedJson {
    id: u32,
    position: [f64; 3],
    orientation: [f64; 4],
    extent_min_m: [f64; 3],
    extent_max_m: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct PlaneJson {
    normal: [f64; 3],
    offset_m: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct WorkspaceJson {
    min: [f64; 3],
    max: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GraspJson {
    position: [f64; 3],
    orientation: [f64; 4],
    width_m: f64,
    #[serde(default)]
    quality: f32,
    object: Option<usize>,
}

fn pose(field: &'static str, position: [f64; 3], orientation: [f64; 4]) -> Result<Isometry3<f64>> {
    mvgrasp_core::pose_from_parts(field, position, orientation).map_err(|e| Error::InvalidInput {
        field,
        reason: e.to_string(),
    })
}

/// The detected objects as boxes and the table as a slab, as `pick` builds
/// them from a planner's answer.
fn scene_obstacles(scene: &SceneJson) -> Result<(Vec<BoxObstacle>, BoxObstacle)> {
    let detected = scene
        .detected
        .iter()
        .map(|o| {
            Ok(ObjectBox {
                id: o.id,
                world_from_object: pose("detected object pose", o.position, o.orientation)?,
                extent_min_m: Vector3::from(o.extent_min_m),
                extent_max_m: Vector3::from(o.extent_max_m),
            })
        })
        .collect::<Result<Vec<_>>>()?;
    let w = &scene.workspace;
    let workspace = Workspace::new(w.min, w.max).map_err(|e| Error::InvalidInput {
        field: "scene.workspace",
        reason: e.to_string(),
    })?;
    let p = &scene.table_plane;
    Ok(obstacles(
        &detected,
        Vector3::from(p.normal),
        p.offset_m,
        &workspace,
    ))
}

/// The answer to one request line, as a JSON value.
fn answer(arm: &Ur5e, config: &PickConfig, line: &str) -> Result<serde_json::Value> {
    let request: Request =
        serde_json::from_str(line).map_err(|e| Error::Protocol(format!("request: {e}")))?;
    match request {
        Request::Fk(q) => {
            crate::ur5e::check_joints("fk", &q)?;
            let flange = arm.forward(&q);
            let (p, r) = (flange.translation.vector, flange.rotation);
            Ok(serde_json::json!({
                "ok": true,
                "position": [p.x, p.y, p.z],
                "orientation": [r.i, r.j, r.k, r.w],
            }))
        }
        Request::ArmReach(()) => {
            let r = config.arm_reach(arm)?;
            Ok(serde_json::json!({
                "ok": true,
                "arm_reach": {
                    "shoulder": [r.shoulder.x, r.shoulder.y, r.shoulder.z],
                    "axis": [r.axis.x, r.axis.y, r.axis.z],
                    "wrist_back_m": r.wrist_back_m,
                    "approach_m": r.approach_m,
                    "max_m": r.max_m,
                    "min_axis_m": r.min_axis_m,
                },
            }))
        }
        Request::RobotBody(q) => {
            crate::ur5e::check_joints("robot_body", &q)?;
            let body: Vec<_> = config
                .robot_body(arm, &q)
                .iter()
                .map(|c| {
                    serde_json::json!({
                        "a": [c.a.x, c.a.y, c.a.z],
                        "b": [c.b.x, c.b.y, c.b.z],
                        "radius_m": c.radius_m,
                    })
                })
                .collect();
            Ok(serde_json::json!({"ok": true, "robot_body": body}))
        }
        Request::Order(order) => {
            let poses = |list: &[PoseJson], field| {
                list.iter()
                    .map(|p| pose(field, p.position, p.orientation))
                    .collect::<Result<Vec<_>>>()
            };
            let grasps = poses(&order.grasps, "grasp pose")?;
            let failed = poses(&order.failed, "failed pose")?;
            Ok(serde_json::json!({"ok": true, "order": config.order_after_failures(&grasps, &failed)}))
        }
        Request::Plan(plan) => {
            let grasps = plan
                .grasps
                .iter()
                .map(|g| {
                    Ok(GraspTarget {
                        world_from_grasp: pose("grasp pose", g.position, g.orientation)?,
                        width_m: g.width_m,
                        quality: g.quality,
                        object: g.object,
                    })
                })
                .collect::<Result<Vec<_>>>()?;
            let mut config = config.clone();
            config.released = plan.released;
            let mut seen_out = SeenObstacles::default();
            let scene = match &plan.scene {
                Some(scene) => {
                    let (objects, table) = scene_obstacles(scene)?;
                    config.obstacles.push(table);
                    let seen = scene
                        .obstacles
                        .iter()
                        .enumerate()
                        .map(|(k, o)| {
                            let b = outside_box(k, Vector3::from(o.min), Vector3::from(o.max)).ok_or_else(
                                || Error::InvalidInput {
                                    field: "scene.obstacles",
                                    reason: format!("{o:?}: finite corners, min <= max"),
                                },
                            )?;
                            if o.object.is_some_and(|i| i >= scene.detected.len()) {
                                return Err(Error::InvalidInput {
                                    field: "scene.obstacles",
                                    reason: format!("{o:?}: `object` is not an index of `detected`"),
                                });
                            }
                            Ok((b, o.object))
                        })
                        .collect::<Result<Vec<_>>>()?;
                    crate::ur5e::check_joints("current", &plan.current)?;
                    seen_out =
                        config.add_seen_obstacles(arm, &seen, &plan.current, scene.robot_body_left_out);
                    objects
                }
                None => Vec::new(),
            };
            let cut: Vec<_> = seen_out.cut.into_iter().map(|(name, _)| name).collect();
            let left_out: Vec<_> = seen_out
                .left_out
                .into_iter()
                .map(|(name, why)| serde_json::json!({"obstacle": name, "why": why}))
                .collect();
            // The first feasible grasp, and why each better-ranked one was refused.
            let mut refused = Vec::new();
            for (index, grasp) in grasps.iter().enumerate() {
                match plan_pick(arm, &config, std::slice::from_ref(grasp), &scene, &plan.current) {
                    Ok(pick) => {
                        return Ok(serde_json::json!({
                            "ok": true,
                            "grasp_index": index,
                            "steps": pick.steps,
                            "refused": refused,
                            "obstacles_left_out": left_out,
                            "obstacles_cut": cut,
                        }));
                    }
                    Err(e @ Error::InvalidInput { .. }) => return Err(e),
                    Err(e) => {
                        refused.push(serde_json::json!({"grasp_index": index, "reason": e.to_string()}))
                    }
                }
            }
            Ok(serde_json::json!({
                "ok": true,
                "grasp_index": null,
                "steps": [],
                "refused": refused,
                "obstacles_left_out": left_out,
                "obstacles_cut": cut,
            }))
        }
    }
}

/// Answers request lines from `input` on `output` until `input` ends.
pub fn serve<R: BufRead, W: Write>(
    arm: &Ur5e,
    config: &PickConfig,
    input: R,
    mut output: W,
) -> std::io::Result<()> {
    for line in input.lines() {
        let line = line?;
        if line.trim().is_empty() {
            continue;
        }
        let value = answer(arm, config, &line)
            .unwrap_or_else(|e| serde_json::json!({"ok": false, "error": e.to_string()}));
        writeln!(output, "{value}")?;
        output.flush()?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ask(line: &str) -> serde_json::Value {
        let mut out = Vec::new();
        serve(
            &Ur5e::default(),
            &PickConfig::default(),
            line.as_bytes(),
            &mut out,
        )
        .unwrap();
        serde_json::from_slice(&out).unwrap()
    }

    #[test]
    fn fk_matches_the_library() {
        let q = [0.3, -1.2, 1.4, -1.6, -1.57, 0.7];
        let v = ask(&format!("{{\"fk\": {q:?}}}"));
        let p = Ur5e::default().forward(&q).translation.vector;
        assert_eq!(v["ok"], true);
        for (i, want) in [p.x, p.y, p.z].iter().enumerate() {
            assert!((v["position"][i].as_f64().unwrap() - want).abs() < 1e-12);
        }
    }

    #[test]
    fn the_robot_body_is_the_pick_configs() {
        let q = [0.1, -1.2, 1.0, -1.4, -1.5, 0.3];
        let v = ask(&serde_json::json!({ "robot_body": q }).to_string());
        assert_eq!(v["ok"], true, "{v}");
        let want = PickConfig::default().robot_body(&Ur5e::default(), &q);
        let got = v["robot_body"].as_array().unwrap();
        assert_eq!(got.len(), want.len());
        for (g, w) in got.iter().zip(&want) {
            let close = |v: &serde_json::Value, want: f64| (v.as_f64().unwrap() - want).abs() < 1e-12;
            for i in 0..3 {
                assert!(close(&g["a"][i], w.a[i]) && close(&g["b"][i], w.b[i]), "{g}");
            }
            assert!(close(&g["radius_m"], w.radius_m), "{g}");
        }
        let bad = ask(r#"{"robot_body": [0.0, 0.0]}"#);
        assert_eq!(bad["ok"], false, "{bad}");
    }

    #[test]
    fn the_arm_reach_is_the_pick_configs() {
        let v = ask("{\"arm_reach\": null}");
        let want = PickConfig::default().arm_reach(&Ur5e::default()).unwrap();
        assert_eq!(v["ok"], true);
        let r = &v["arm_reach"];
        assert_eq!(r["shoulder"][2].as_f64(), Some(want.shoulder.z));
        assert_eq!(r["axis"][2].as_f64(), Some(1.0));
        for (key, value) in [
            ("wrist_back_m", want.wrist_back_m),
            ("approach_m", want.approach_m),
            ("max_m", want.max_m),
            ("min_axis_m", want.min_axis_m),
        ] {
            assert_eq!(r[key].as_f64(), Some(value), "{key}");
        }
        // The UR5e's shoulder 0.1625 m over the base, the wrist centre
        // 0.233 + 0.0996 m behind the fingertips, reach sqrt(0.9169^2 + 0.1333^2).
        assert!((want.shoulder.z - 0.1625).abs() < 1e-12);
        assert!((want.wrist_back_m - 0.3326).abs() < 1e-12);
        assert!((want.max_m - 0.92654).abs() < 1e-5);
    }

    #[test]
    fn a_plan_ends_its_straight_moves_on_the_step_joints() {
        // Top-down grasp 0.45 m in front of the base (world = base here).
        let line = r#"{"plan": {"grasps": [
            {"position": [0.0, -5.0, 0.05], "orientation": [1, 0, 0, 0], "width_m": 0.05, "object": 0},
            {"position": [0.0, -0.45, 0.05], "orientation": [1, 0, 0, 0], "width_m": 0.05, "object": 1}],
            "current": [0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0]}}"#;
        let v = ask(&line.replace('\n', " "));
        assert_eq!(v["ok"], true, "{v}");
        assert_eq!(v["grasp_index"], 1);
        assert_eq!(v["refused"].as_array().unwrap().len(), 1);
        assert!(
            v["refused"][0]["reason"]
                .as_str()
                .unwrap()
                .contains("unreachable")
        );
        let steps = v["steps"].as_array().unwrap();
        let approach = steps.iter().find(|s| s["name"] == "approach").unwrap();
        let path = approach["path"].as_array().unwrap();
        assert!(path.len() >= 10, "a 10 cm approach sampled every cm");
        let (last, end) = (path.last().unwrap(), &approach["joints"]);
        for i in 0..6 {
            assert!(
                (last[i].as_f64().unwrap() - end[i].as_f64().unwrap()).abs() < 1e-9,
                "{last} vs {end}"
            );
        }
    }

    /// `released` chooses the spot over the basket, in turn; absent, the first.
    #[test]
    fn released_chooses_where_over_the_basket() {
        let arm = Ur5e::default();
        let config = PickConfig {
            release_offsets_m: vec![[0.05, 0.05], [-0.05, -0.05]],
            ..PickConfig::default()
        };
        let over_the_basket = |released: Option<usize>| {
            let mut plan = serde_json::json!({
                "grasps": [{"position": [0.0, -0.45, 0.05], "orientation": [1, 0, 0, 0], "width_m": 0.05}],
                "current": crate::ur5e::HOME,
            });
            if let Some(n) = released {
                plan["released"] = n.into();
            }
            let mut out = Vec::new();
            let line = serde_json::json!({ "plan": plan }).to_string();
            serve(&arm, &config, line.as_bytes(), &mut out).unwrap();
            let v: serde_json::Value = serde_json::from_slice(&out).unwrap();
            assert_eq!(v["ok"], true, "{v}");
            let step = v["steps"]
                .as_array()
                .unwrap()
                .iter()
                .find(|s| s["name"] == "over the basket")
                .unwrap();
            let q: Joints = serde_json::from_value(step["joints"].clone()).unwrap();
            let tcp = config.world_from_base * arm.forward(&q) * config.flange_from_tcp;
            tcp.translation.vector - config.world_from_drop.translation.vector
        };
        for (released, [x, y]) in [
            (None, [0.05, 0.05]),
            (Some(0), [0.05, 0.05]),
            (Some(1), [-0.05, -0.05]),
            (Some(2), [0.05, 0.05]),
        ] {
            let off = over_the_basket(released);
            assert!(
                (off - Vector3::new(x, y, 0.0)).norm() < 1e-6,
                "{released:?}: {off:?}"
            );
        }
    }

    /// One top-down grasp of a 4 cm object at (0, -0.45), the arm at home,
    /// the scene ending in `rest` (its `obstacles` and any other field).
    fn plan_among(rest: &str) -> serde_json::Value {
        let line = format!(
            r#"{{"plan": {{"grasps": [
            {{"position": [0.0, -0.45, 0.05], "orientation": [1, 0, 0, 0], "width_m": 0.05, "object": 0}}],
            "scene": {{"detected": [{{"id": 0, "position": [0.0, -0.45, 0.03], "orientation": [0, 0, 0, 1],
              "extent_min_m": [-0.02, -0.02, -0.03], "extent_max_m": [0.02, 0.02, 0.03]}}],
              "table_plane": {{"normal": [0, 0, 1], "offset_m": 0.0}},
              "workspace": {{"min": [-0.3, -0.7, -0.05], "max": [0.3, -0.3, 0.4]}},
              {rest}}},
            "current": [0.0, -1.5708, 1.5708, -1.5708, -1.5708, 0.0]}}}}"#
        );
        ask(&line.replace('\n', " "))
    }

    /// The planner's boxes outside the workspace: one in the arm's way
    /// refuses the pick and names itself; one far off changes nothing; one
    /// over the robot's base is taken for the cell and said so.
    #[test]
    fn boxes_seen_outside_the_workspace_keep_the_arm_clear() {
        let plan = |obstacles: &str| plan_among(&format!(r#""obstacles": [{obstacles}]"#));
        let free = plan("");
        assert_eq!(
            (free["ok"].clone(), free["grasp_index"].clone()),
            (true.into(), 0.into()),
            "{free}"
        );
        let far = plan(r#"{"min": [0.7, 0.7, 0.0], "max": [0.8, 0.8, 0.2]}"#);
        assert_eq!(far["grasp_index"], 0, "{far}");
        assert_eq!(far["obstacles_left_out"], serde_json::json!([]));
        // Over the grasp, where the wrist comes down.
        let blocking = plan(r#"{"min": [-0.06, -0.52, 0.25], "max": [0.06, -0.38, 0.5]}"#);
        assert_eq!(blocking["grasp_index"], serde_json::Value::Null, "{blocking}");
        assert!(
            blocking["refused"][0]["reason"]
                .as_str()
                .unwrap()
                .contains("obstacle 0"),
            "{blocking}"
        );
        let base = plan(r#"{"min": [-0.05, -0.05, 0.0], "max": [0.05, 0.05, 0.1]}"#);
        assert_eq!(base["grasp_index"], 0, "{base}");
        assert_eq!(
            base["obstacles_left_out"][0]["why"], "over the robot's base",
            "{base}"
        );
        // The same box as the rest of the grasped object (cut off by the
        // workspace's border): not in its own grasp's way.
        let own = plan(r#"{"min": [-0.06, -0.52, 0.25], "max": [0.06, -0.38, 0.5], "object": 0}"#);
        assert_eq!(own["grasp_index"], 0, "{own}");
        let stray = plan(r#"{"min": [0.7, 0.7, 0.0], "max": [0.8, 0.8, 0.2], "object": 3}"#);
        assert_eq!(stray["ok"], false, "{stray}");
        let bad = plan(r#"{"min": [0.0, 0.0, 0.0], "max": [-1.0, 0.0, 0.0]}"#);
        assert_eq!(bad["ok"], false, "{bad}");
        assert!(
            bad["error"].as_str().unwrap().contains("scene.obstacles"),
            "{bad}"
        );
    }

    /// A box under the forearm where the arm stands (home), its top 3 cm
    /// into it: taken for the arm itself unless the planner was asked with
    /// the robot's body; then kept, cut back clear of the arm, and said so.
    #[test]
    fn a_box_against_the_arm_is_kept_cut_when_the_body_was_left_out() {
        let plan = |body: bool| {
            plan_among(&format!(
                r#""obstacles": [{{"min": [-0.25, -0.1, 0.25], "max": [-0.15, 0.1, 0.5575]}}],
                "robot_body_left_out": {body}"#
            ))
        };
        let told = plan(true);
        assert_eq!(told["ok"], true, "{told}");
        assert_eq!(told["obstacles_cut"], serde_json::json!(["obstacle 0"]), "{told}");
        assert_eq!(told["obstacles_left_out"], serde_json::json!([]), "{told}");
        let not_told = plan(false);
        assert_eq!(not_told["obstacles_cut"], serde_json::json!([]), "{not_told}");
        assert_eq!(
            not_told["obstacles_left_out"][0]["why"],
            crate::collision::TOUCHES_ARM,
            "{not_told}"
        );
    }

    #[test]
    fn the_order_puts_a_failed_spot_last() {
        // Grasp 0 is the failed pick turned half a turn about its approach
        // (the same closing line); grasp 1 is 5 cm away.
        let line = r#"{"order": {"grasps": [
            {"position": [0.3, 0.0, 0.05], "orientation": [0, 1, 0, 0]},
            {"position": [0.35, 0.0, 0.05], "orientation": [1, 0, 0, 0]}],
            "failed": [{"position": [0.3, 0.0, 0.05], "orientation": [1, 0, 0, 0]}]}}"#;
        let v = ask(&line.replace('\n', " "));
        assert_eq!(v["ok"], true, "{v}");
        assert_eq!(v["order"], serde_json::json!([1, 0]));
        let none_failed = ask(
            r#"{"order": {"grasps": [{"position": [0, 0, 0], "orientation": [0, 0, 0, 1]}], "failed": []}}"#,
        );
        assert_eq!(none_failed["order"], serde_json::json!([0]));
        let bad = ask(
            r#"{"order": {"grasps": [], "failed": [{"position": [0, 0, 0], "orientation": [0, 0, 0, 0]}]}}"#,
        );
        assert_eq!(bad["ok"], false);
        assert!(bad["error"].as_str().unwrap().contains("failed pose"), "{bad}");
    }

    #[test]
    fn bad_lines_are_answered_and_the_loop_goes_on() {
        let mut out = Vec::new();
        let input = "not json\n{\"fk\": [0, 0, 0, 0, 0]}\n{\"fk\": [0, 0, 0, 0, 0, 0]}\n";
        serve(
            &Ur5e::default(),
            &PickConfig::default(),
            input.as_bytes(),
            &mut out,
        )
        .unwrap();
        let lines: Vec<serde_json::Value> = String::from_utf8(out)
            .unwrap()
            .lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect();
        assert_eq!(lines.len(), 3);
        assert_eq!(lines[0]["ok"], false);
        assert_eq!(lines[1]["ok"], false);
        assert_eq!(lines[2]["ok"], true);
    }
}
