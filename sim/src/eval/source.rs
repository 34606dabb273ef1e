//! Where grasps come from: the planner in process, and the same keeping the views it read.

use super::*;

/// A grasp of a plan, with where its object was seen.
#[derive(Debug, Clone, PartialEq)]
pub struct PlannedGrasp {
    /// The grasp pose in the world.
    pub world_from_grasp: Isometry3<f64>,
    /// Opening (m).
    pub width_m: f64,
    /// Predicted quality.
    pub quality: f32,
    /// Centroid of the detected object it grasps (world).
    pub object_centroid: Point3<f64>,
    /// The view it was found in.
    pub view: ViewAxis,
    /// Its peak pixel `[u, v]` in that view.
    pub pixel: [u32; 2],
    /// What the planner's hand check changed about it after decoding (none
    /// from a server that does not say).
    pub repairs: Repairs,
}

/// Whatever plans: the pipeline in this process, or a running server.
pub trait GraspSource {
    /// The grasps for `frame` under `options`, best first, at most
    /// `options.max_grasps`; empty when none reaches `options.min_quality`.
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>>;
}

/// The planner and a network in this process.
pub struct InProcess<'a> {
    /// The pipeline.
    pub planner: &'a Planner,
    /// The network.
    pub net: &'a mut dyn GraspNet,
}

impl InProcess<'_> {
    fn plan(&mut self, frame: &Frame, workspace: Workspace, options: &PlanOptions) -> Result<Plan> {
        let bytes = frame.depth_le_bytes();
        let input = frame.scene_input(&bytes, workspace);
        self.planner
            .plan(&input, options, self.net)
            .map_err(|e| Error::Scene(format!("planner: {e}")))
    }

    /// [`GraspSource::grasps`], each grasp with the view it came from as the
    /// network read it (`size x size`, the contract's normalisation).
    pub fn grasps_with_views(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<(PlannedGrasp, Vec<f32>)>> {
        let keeping = PlanOptions {
            keep_views: true,
            ..options.clone()
        };
        let plan = self.plan(frame, workspace, &keeping)?;
        plan.grasps
            .iter()
            .filter_map(|g| {
                let planned = planned_grasp(&plan, g)?;
                let view = plan
                    .debug_views
                    .iter()
                    .find(|d| d.object_id == g.object_id && d.view.axis == g.view);
                Some(match view {
                    Some(d) => Ok((planned, d.view.image.clone())),
                    None => Err(Error::Scene(format!(
                        "planner: grasp on object {} names a {} view it did not keep",
                        g.object_id,
                        g.view.name()
                    ))),
                })
            })
            .collect()
    }
}

/// `g` of `plan` with where its object was seen; `None` for a grasp on no
/// object of the plan.
fn planned_grasp(plan: &Plan, g: &Grasp) -> Option<PlannedGrasp> {
    let object = plan.objects.iter().find(|o| o.id == g.object_id)?;
    Some(PlannedGrasp {
        world_from_grasp: g.world_from_grasp,
        width_m: g.width_m,
        quality: g.quality,
        object_centroid: Point3::from(object.frame.world_from_object.translation.vector),
        view: g.view,
        pixel: g.pixel,
        repairs: g.repairs,
    })
}

impl GraspSource for InProcess<'_> {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>> {
        let plan = self.plan(frame, workspace, options)?;
        Ok(plan
            .grasps
            .iter()
            .filter_map(|g| planned_grasp(&plan, g))
            .collect())
    }
}

/// An in-process source that keeps every grasp it offers with the view it
/// came from, frame by frame (`sim eval --attempt-views`): after an
/// episode, [`ViewKeeping::rows`] gives each attempt the view the network read,
/// so physics outcomes can be learned from.
pub struct ViewKeeping<'a> {
    /// The planner and network.
    pub inner: InProcess<'a>,
    /// Per call (frame): the grasps offered, best first, with their views.
    frames: Vec<Vec<(PlannedGrasp, Vec<f32>)>>,
}

/// One row of `sim eval --attempt-views`: an attempt with the view its
/// grasp came from.
#[derive(Debug, Clone, PartialEq)]
pub struct AttemptRow<'a> {
    /// The frame: attempts the episode had made before it.
    pub step: usize,
    /// The grasp's place in the planner's ranking on that frame (0 best).
    pub rank: usize,
    /// `false`: the episode's own attempt. `true`: a grasp ranked below
    /// it, tried from the same state and forgotten ([`alternative_attempts`]).
    pub alternative: bool,
    /// What it came to.
    pub attempt: Attempt,
    /// The view as the network read it.
    pub view: &'a [f32],
}

impl<'a> ViewKeeping<'a> {
    /// Keeps the views of `inner`'s grasps.
    pub fn new(inner: InProcess<'a>) -> Self {
        Self {
            inner,
            frames: Vec::new(),
        }
    }

    /// The rows `sim eval --attempt-views` writes for `episode` (planned by
    /// this source, from its first call on): each attempt with the view its
    /// grasp came from (none where the tried pose is none this source
    /// offered on that frame), followed, when
    /// `alternatives` > 0, by up to that many grasps the planner ranked
    /// below it on the same frame, tried from `scenes[step]` (the scene as
    /// that frame showed it) and forgotten ([`alternative_attempts`]).
    /// Fails when `alternatives` > 0 and a frame's scene is missing.
    pub fn rows(
        &self,
        episode: &Episode,
        scenes: &[Scene],
        alternatives: usize,
        config: &EpisodeConfig,
    ) -> Result<Vec<AttemptRow<'_>>> {
        if alternatives > 0 && scenes.len() < episode.attempts.len() {
            return Err(Error::Invalid {
                field: "attempt alternatives",
                reason: format!("{} scenes for {} attempts", scenes.len(), episode.attempts.len()),
            });
        }
        let mut rows = Vec::new();
        for (step, a) in episode.attempts.iter().enumerate() {
            let Some(offered) = self.frames.get(step) else {
                continue;
            };
            let Some(rank) = offered
                .iter()
                .position(|(g, _)| g.world_from_grasp == a.world_from_grasp)
            else {
                continue;
            };
            rows.push(AttemptRow {
                step,
                rank,
                alternative: false,
                attempt: a.clone(),
                view: &offered[rank].1,
            });
            if alternatives == 0 {
                continue;
            }
            let grasps: Vec<PlannedGrasp> = offered.iter().map(|(g, _)| g.clone()).collect();
            for (rank, attempt) in
                alternative_attempts(&scenes[step], &grasps, &a.world_from_grasp, alternatives, config)
            {
                rows.push(AttemptRow {
                    step,
                    rank,
                    alternative: true,
                    attempt,
                    view: &offered[rank].1,
                });
            }
        }
        Ok(rows)
    }
}

impl GraspSource for ViewKeeping<'_> {
    fn grasps(
        &mut self,
        frame: &Frame,
        workspace: Workspace,
        options: &PlanOptions,
    ) -> Result<Vec<PlannedGrasp>> {
        let offered = self.inner.grasps_with_views(frame, workspace, options)?;
        let grasps = offered.iter().map(|(g, _)| g.clone()).collect();
        self.frames.push(offered);
        Ok(grasps)
    }
}
