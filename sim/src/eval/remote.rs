//! Grasps from a running service over gRPC.

use mvgrasp_client::request::{depth_request, pose_from_message};
use mvgrasp_client::{PlannerClient, pb};

use super::*;

/// A running server, over gRPC.
/// Each call blocks on its own single-threaded runtime, so call it from
/// plain threads, not from inside an async runtime.
pub struct Remote {
    runtime: tokio::runtime::Runtime,
    client: PlannerClient,
}

impl Remote {
    /// Connects to the server at `endpoint` (`http://host:port`).
    pub fn connect(endpoint: &str) -> Result<Self> {
        let failed = |e: &dyn std::fmt::Display| Error::Scene(format!("connecting to {endpoint}: {e}"));
        let runtime = tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()
            .map_err(|e| failed(&e))?;
        let client = runtime
            .block_on(PlannerClient::connect(endpoint))
            .map_err(|e| failed(&e))?;
        Ok(Self { runtime, client })
    }

    /// The served model's contract and provenance.
    pub fn model_info(&mut self) -> Result<pb::ModelInfo> {
        self.runtime
            .block_on(self.client.model_info())
            .map_err(|e| Error::Scene(format!("server: {e}")))
    }
}

impl GraspSource for Remote {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>> {
        let c = &frame.camera;
        let k = c.intrinsics;
        let mut request = depth_request(
            c.width,
            c.height,
            &frame.depth_mm,
            pb::CameraIntrinsics {
                fx: k.fx,
                fy: k.fy,
                cx: k.cx,
                cy: k.cy,
            },
            &c.world_from_camera,
            Some((workspace.min, workspace.max)),
        );
        request.gripper = Some(pb::Gripper {
            max_width_m: options.gripper.max_width_m,
            finger_width_m: options.gripper.finger_width_m,
            finger_depth_m: options.gripper.finger_depth_m,
        });
        request.max_grasps = u32::try_from(options.max_grasps).unwrap_or(u32::MAX);
        request.min_quality = Some(options.min_quality);
        request.view_cascade = Some(options.view_cascade);
        request.view_policy = match options.view_policy {
            ViewPolicy::Entropy => pb::ViewPolicy::Entropy,
            ViewPolicy::All => pb::ViewPolicy::All,
            ViewPolicy::TopDown => pb::ViewPolicy::TopDown,
            ViewPolicy::Random { seed } => {
                request.random_seed = seed;
                pb::ViewPolicy::Random
            }
        } as i32;
        let response = self
            .runtime
            .block_on(self.client.plan(request))
            .map_err(|e| Error::Scene(format!("server: {e}")))?;
        response
            .grasps
            .iter()
            .filter_map(|g| {
                let object = response.objects.iter().find(|o| o.id == g.object_id)?;
                let view = match view_axis(g.view()) {
                    Some(view) => view,
                    None => {
                        return Some(Err(Error::Scene(format!(
                            "server: grasp {:?} names no view",
                            g.pose
                        ))));
                    }
                };
                Some(Ok(PlannedGrasp {
                    world_from_grasp: pose_from_message(g.pose.as_ref()),
                    width_m: g.width_m,
                    quality: g.quality,
                    object_centroid: Point3::from(
                        pose_from_message(object.world_from_object.as_ref())
                            .translation
                            .vector,
                    ),
                    view,
                    pixel: [g.pixel_u, g.pixel_v],
                    repairs: g.repairs.map_or_else(Repairs::default, |r| Repairs {
                        refit: r.refit,
                        turned_away: r.turned_away,
                        squared: r.squared,
                        deepened: r.deepened,
                        out_of_view: r.out_of_view,
                    }),
                }))
            })
            .collect()
    }
}

/// The planner's view of a message's view axis; `None` for an unspecified one.
fn view_axis(axis: pb::ViewAxis) -> Option<ViewAxis> {
    match axis {
        pb::ViewAxis::Unspecified => None,
        pb::ViewAxis::Top => Some(ViewAxis::Top),
        pb::ViewAxis::Front => Some(ViewAxis::Front),
        pb::ViewAxis::Side => Some(ViewAxis::Side),
        pb::ViewAxis::TopFront => Some(ViewAxis::TopFront),
        pb::ViewAxis::TopSide => Some(ViewAxis::TopSide),
    }
}
