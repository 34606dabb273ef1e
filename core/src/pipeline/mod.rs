//! The whole method, split where a server batches across requests:
//! [`Planner::prepare`] (frame -> views to infer), the network, and
//! [`Planner::finish`] (maps -> ranked grasps). [`Planner::plan`] chains them.
//!
//! Files: `options` (what a request asks, how the planner is configured),
//! `plan` (the answer), `prepared` (a frame between the two halves, the
//! view cascade's order), `vet` (the hand check of the ranked grasps);
//! the planner's stages are here.

mod options;
mod plan;
mod prepared;
mod vet;

pub use options::{ApproachCone, ArmReach, PlanOptions, PlannerConfig, SceneInput};
use plan::RankedLast;
pub use plan::{
    DebugView, DetectedObject, ObjectRefusals, Plan, Refusals, Segmentation, StageTimings, ViewReport,
};
pub use prepared::{Finished, Prepared};
use prepared::{PreparedObject, Vetted, cascade_order};
pub use vet::approach_of;
use vet::{Verdicts, Vetting};

use std::time::{Duration, Instant};

use nalgebra::{Point3, Vector3};

use crate::decode::{
    Grasp, Obstacle, RankConfig, ViewPlacement, decode_view, lever_arm_m, rank_grasps_scored,
};
use crate::error::{Error, Result};
use crate::infer::{GraspMaps, GraspNet, ModelContract, NORMALISATION_CUBE_V1, ViewBatch};
use crate::object::{ObjectFrame, object_frame};
use crate::segment::{
    BodyCapsule, BodyFilter, Detected, ImagePoints, euclidean_clusters, fit_table, fixed_order,
    outside_obstacles, split_at_creases,
};
use crate::select::select_views;
use crate::sensor::{
    BlockMask, FieldOfView, SensorInput, random_world_points, world_points, world_points_above,
    world_points_outside,
};
use crate::view::{OrthoView, ViewAxis};

/// Below this many usable random readings the table is fitted on all of them.
const MIN_RANDOM_POINTS_TO_FIT: usize = 256;

/// The pipeline, configured once for a model contract.
#[derive(Debug, Clone)]
pub struct Planner {
    config: PlannerConfig,
    contract: ModelContract,
}

impl Planner {
    /// A planner for networks that speak `contract`.
    pub fn new(config: PlannerConfig, contract: ModelContract) -> Result<Self> {
        if contract.normalisation != NORMALISATION_CUBE_V1 {
            return Err(Error::Contract {
                key: crate::infer::keys::NORMALISATION.into(),
                reason: format!("{:?} is not supported", contract.normalisation),
            });
        }
        if config.views.is_empty() {
            return Err(Error::invalid("views", "at least one view axis is needed"));
        }
        Ok(Self { config, contract })
    }

    /// The contract views are rendered for.
    pub fn contract(&self) -> &ModelContract {
        &self.contract
    }

    /// The settings.
    pub fn config(&self) -> &PlannerConfig {
        &self.config
    }

    /// Frame -> table -> the object points -> clusters (split at creases
    /// for a depth image): the stages before the object frames, with no
    /// robot body left out.
    pub fn segment(&self, scene: &SceneInput<'_>) -> Result<Segmentation> {
        self.segment_timed(scene, &[], &mut StageTimings::default())
    }

    fn segment_timed(
        &self,
        scene: &SceneInput<'_>,
        robot_body: &[BodyCapsule],
        timings: &mut StageTimings,
    ) -> Result<Segmentation> {
        let mut clock = Stopwatch::start();

        // The table is fitted on random readings; a grid pass then marks the
        // blocks near what stands on it, and one full-resolution pass over
        // those blocks keeps the object points: the table is never converted.
        let (sensor, pose, workspace) = (&scene.sensor, &scene.world_from_camera, &scene.workspace);
        let table_config = &self.config.table;
        let mut sample = random_world_points(
            sensor,
            pose,
            workspace,
            table_config.sample_points,
            table_config.seed,
        )?;
        if sample.points.len() < MIN_RANDOM_POINTS_TO_FIT {
            // Few usable readings: look at all of them (this also names the
            // cause when there is none).
            sample = world_points(sensor, pose, workspace)?;
        }
        clock.lap(&mut timings.sensor);
        let table = fit_table(&sample.points, table_config)?;
        clock.lap(&mut timings.table);
        let half_space = table.above(table_config.object_min_height_m);
        let near = match sensor {
            SensorInput::Depth(frame) if table_config.mask_stride > 1 => Some(BlockMask::from_frame(
                frame,
                pose,
                workspace,
                &half_space,
                table_config.mask_stride,
            )?),
            _ => None,
        };
        let mut above = world_points_above(sensor, pose, workspace, &half_space, near.as_ref())?;
        BodyFilter::new(robot_body, workspace).leave_out(&mut above.points, &mut above.pixels);
        clock.lap(&mut timings.sensor_objects);

        let cluster_config = &self.config.cluster;
        let mut clusters = euclidean_clusters(&above.points, cluster_config);
        if let (Some(crease), SensorInput::Depth(frame)) = (&cluster_config.crease, sensor) {
            let rotation = pose.rotation;
            let axis = rotation * Vector3::z();
            let t = pose.translation.vector;
            let image = ImagePoints {
                points: &above.points,
                pixels: &above.pixels,
                width: frame.width as usize,
                origin: [t.x as f32, t.y as f32, t.z as f32],
                axis: [axis.x as f32, axis.y as f32, axis.z as f32],
                focal_px: frame.intrinsics.fx as f32,
            };
            let split;
            (clusters, split) = split_at_creases(&image, clusters, cluster_config.tolerance_m, crease);
            if split {
                clusters = fixed_order(&above.points, clusters, cluster_config.max_objects);
            }
        }
        clock.lap(&mut timings.cluster);
        Ok(Segmentation {
            table,
            points: above.points,
            pixels: above.pixels,
            clusters,
        })
    }

    /// Frame -> objects -> frames -> views -> entropy -> the batch to infer.
    pub fn prepare(&self, scene: &SceneInput<'_>, options: &PlanOptions) -> Result<Prepared> {
        options.validate()?;
        let mut timings = StageTimings::default();
        let Segmentation {
            table,
            points: above,
            clusters,
            ..
        } = self.segment_timed(scene, &options.robot_body, &mut timings)?;
        let mut clock = Stopwatch::start();
        let obstacles = match &options.obstacle_region {
            None => (Vec::new(), 0),
            Some(region) => {
                let config = &self.config.obstacles;
                let half_space = table.above(self.config.table.object_min_height_m);
                let mut outside = world_points_outside(
                    &scene.sensor,
                    &scene.world_from_camera,
                    region,
                    &scene.workspace,
                    &half_space,
                    config.stride,
                )?;
                BodyFilter::new(&options.robot_body, region).leave_out(&mut outside, &mut Vec::new());
                let detected = Detected {
                    points: &above,
                    objects: &clusters,
                };
                outside_obstacles(&outside, detected, &table, config)
            }
        };
        // Counted with the points above the table (the stage laps, not adds).
        let mut outside_time = Duration::ZERO;
        clock.lap(&mut outside_time);
        timings.sensor_objects += outside_time;

        let camera = Point3::from(scene.world_from_camera.translation.vector);
        let framed: Vec<(ObjectFrame, Vec<[f32; 3]>)> = clusters
            .iter()
            .map(|c| object_frame(&above, c, &camera))
            .collect();
        clock.lap(&mut timings.frames);

        let (l, s) = (self.contract.input_size_px, self.contract.pixel_size_m);
        let rendered: Vec<Vec<OrthoView>> = framed
            .iter()
            .map(|(frame, local)| {
                let camera_in_object = frame.world_from_object.inverse_transform_point(&camera);
                let plus_y = camera_in_object.y >= 0.0;
                let extent = frame.extent_f32();
                self.config
                    .views
                    .iter()
                    .map(|&axis| OrthoView::render_within(axis, plus_y, local, extent, l, s))
                    .collect()
            })
            .collect();
        clock.lap(&mut timings.views);

        let mut batch = ViewBatch::new(l);
        let mut inferred = Vec::new();
        let mut untried = Vec::with_capacity(rendered.len());
        let mut objects = Vec::with_capacity(rendered.len());
        for (index, ((frame, points), views)) in framed.into_iter().zip(rendered).enumerate() {
            let id = index as u32;
            let entropies: Vec<f64> = views.iter().map(|v| v.entropy).collect();
            let candidates = views_within(options.approach_cone.as_ref(), &frame, &views);
            let axes: Vec<ViewAxis> = candidates.iter().map(|&v| views[v].axis).collect();
            let candidate_entropies: Vec<f64> = candidates.iter().map(|&v| entropies[v]).collect();
            let chosen: Vec<usize> = select_views(options.view_policy, &axes, &candidate_entropies, id)
                .into_iter()
                .map(|i| candidates[i])
                .collect();
            for &v in &chosen {
                batch.push(&views[v].image);
                inferred.push((index, v));
            }
            let mut next = cascade_order(&entropies, &chosen);
            next.retain(|v| candidates.contains(v));
            untried.push(next);
            let reports = views
                .iter()
                .zip(&entropies)
                .enumerate()
                .map(|(v, (view, &entropy))| ViewReport {
                    axis: view.axis,
                    entropy,
                    inferred: chosen.contains(&v),
                })
                .collect();
            objects.push(PreparedObject {
                object: DetectedObject {
                    id,
                    frame,
                    views: reports,
                    refused: ObjectRefusals::default(),
                },
                views,
                points,
            });
        }
        clock.lap(&mut timings.select);

        let view = match &scene.sensor {
            SensorInput::Depth(frame) => Some(FieldOfView::of(frame, &scene.world_from_camera)),
            SensorInput::Cloud(_) => None,
        };
        Ok(Prepared {
            covered: vec![false; objects.len()],
            objects,
            table,
            obstacles,
            view,
            inferred,
            batch,
            untried,
            earlier: Vec::new(),
            decoded: Vec::new(),
            verdicts: Verdicts::default(),
            options: options.clone(),
            timings,
        })
    }

    /// Maps of the prepared batch -> ranked grasps, or, with
    /// [`PlanOptions::view_cascade`], the next views of the objects that have
    /// no grasp yet (clearing `min_quality` and the hand check) while any
    /// such object has a view left. Every round's maps count in the plan.
    pub fn finish_or_cascade(&self, mut prepared: Prepared, maps: GraspMaps) -> Result<Finished> {
        maps.check_matches(&prepared.batch)?;
        if prepared.options.view_cascade && prepared.untried.iter().any(|u| !u.is_empty()) {
            let start = Instant::now();
            // Whether an object has a grasp that passes depends on its own
            // views alone, and earlier rounds' views are already counted:
            // only this round's views are decoded to update the cover.
            let fresh = self.decode_round(&mut prepared, &maps);
            let newly = self.objects_with_grasps(&mut prepared, fresh.clone());
            for (covered, newly) in prepared.covered.iter_mut().zip(newly) {
                *covered |= newly;
            }
            prepared.decoded.extend(fresh);
            let mut batch = ViewBatch::new(prepared.batch.size_px);
            let mut next = Vec::new();
            let objects = prepared.objects.iter_mut().zip(&mut prepared.untried);
            for (index, ((o, untried), &covered)) in objects.zip(&prepared.covered).enumerate() {
                if covered || untried.is_empty() {
                    continue;
                }
                let v = untried.remove(0);
                batch.push(&o.views[v].image);
                o.object.views[v].inferred = true;
                next.push((index, v));
            }
            prepared.timings.decode += start.elapsed();
            if !next.is_empty() {
                let this_round = std::mem::replace(&mut prepared.inferred, next);
                prepared.earlier.push((this_round, maps));
                prepared.batch = batch;
                return Ok(Finished::More(Box::new(prepared)));
            }
            // Every round is decoded: rank what they gave.
            return self
                .rank_decoded(prepared, &maps, Instant::now())
                .map(|plan| Finished::Plan(Box::new(plan)));
        }
        self.finish(prepared, &maps)
            .map(|plan| Finished::Plan(Box::new(plan)))
    }

    /// Which objects have at least one grasp that clears `min_quality` and
    /// the hand check in the maps so far.
    fn objects_with_grasps(&self, prepared: &mut Prepared, candidates: Vec<Grasp>) -> Vec<bool> {
        let options = PlanOptions {
            max_grasps: usize::MAX,
            keep_views: false,
            ..prepared.options.clone()
        };
        // One grasp per object answers the question: the check stops there.
        let mut verdicts = std::mem::take(&mut prepared.verdicts);
        let vetted = self.vet_and_rank(prepared, candidates, &options, 1, &mut verdicts);
        prepared.verdicts = verdicts;
        let mut covered = vec![false; prepared.objects.len()];
        for g in &vetted.ranked.grasps {
            if let Some(i) = prepared.objects.iter().position(|o| o.object.id == g.object_id) {
                covered[i] = true;
            }
        }
        covered
    }

    /// The candidate grasps of the current round's views (`prepared.inferred`,
    /// the rows of `maps`), in batch order, before the approach cone and the
    /// hand check; the peaks that gave none are counted on their object
    /// (`refused.too_wide`, `refused.no_pose`).
    fn decode_round(&self, prepared: &mut Prepared, maps: &GraspMaps) -> Vec<Grasp> {
        let options = &prepared.options;
        let mut grasps = Vec::new();
        for (batch_index, &(object, view)) in prepared.inferred.iter().enumerate() {
            let o = &prepared.objects[object];
            let placement = ViewPlacement {
                view: &o.views[view],
                world_from_object: &o.object.frame.world_from_object,
                object_id: o.object.id,
            };
            let decoded = decode_view(
                &placement,
                maps,
                batch_index,
                &self.contract,
                &options.gripper,
                &prepared.table,
                options.min_quality,
                &self.config.decode,
            );
            grasps.extend(decoded.grasps);
            let lost = &mut prepared.objects[object].object.refused;
            lost.too_wide += decoded.too_wide;
            lost.no_pose += decoded.no_pose;
        }
        grasps
    }

    /// The candidates (decoded, [`Self::decode_round`]) through the approach
    /// cone, the hand check and the ranking: the grasps, and what the check
    /// refused, deferred or turned. `verdicts`: the hand check's answers
    /// earlier in this call, kept for the next.
    fn vet_and_rank(
        &self,
        prepared: &Prepared,
        mut grasps: Vec<Grasp>,
        options: &PlanOptions,
        max_per_object: usize,
        verdicts: &mut Verdicts,
    ) -> Vetted {
        let (objects, table, view) = (&prepared.objects, &prepared.table, &prepared.view);
        // Approaches and positions the robot cannot take: dropped before
        // anything else.
        let mut per_object = vec![ObjectRefusals::default(); objects.len()];
        let index_of = |id: u32| objects.iter().position(|o| o.object.id == id);
        if let Some(cone) = &options.approach_cone {
            grasps.retain(|g| {
                let within = cone.allows(&approach_of(g));
                if let (false, Some(i)) = (within, index_of(g.object_id)) {
                    per_object[i].outside_approach_cone += 1;
                }
                within
            });
        }
        if let Some(reach) = &options.arm_reach {
            grasps.retain(|g| {
                let reached = reach.reaches(&g.world_from_grasp.translation.vector, &approach_of(g));
                if let (false, Some(i)) = (reached, index_of(g.object_id)) {
                    per_object[i].out_of_reach += 1;
                }
                reached
            });
        }
        let obstacles: Vec<Obstacle<'_>> = objects
            .iter()
            .map(|o| Obstacle {
                world_from_object: &o.object.frame.world_from_object,
                extent_min_m: &o.object.frame.extent_min_m,
                extent_max_m: &o.object.frame.extent_max_m,
                points: &o.points,
            })
            .collect();
        let mut turned_square = 0;
        let vetting = Vetting {
            hand: &self.config.hand,
            gripper: &options.gripper,
            table,
            obstacles: &obstacles,
            view: view.as_ref(),
            table_clearance_m: self.config.decode.table_clearance_m,
        };
        let centre_weight = self.config.decode.centre_weight;
        let score = |g: &Grasp| match index_of(g.object_id) {
            Some(i) if centre_weight != 0.0 => {
                let centre = objects[i].object.frame.world_from_object.translation.vector;
                g.quality - centre_weight * (lever_arm_m(g, &centre) / 0.1) as f32
            }
            _ => g.quality,
        };
        let ranked = rank_grasps_scored(
            grasps,
            &RankConfig {
                min_quality: options.min_quality,
                max_per_object,
                max_grasps: options.max_grasps,
            },
            score,
            |g| {
                let own = index_of(g.object_id);
                let checked = verdicts.check(g, own, &vetting);
                checked.count(own, &mut per_object, &mut turned_square);
                checked.verdict
            },
        );
        Vetted {
            ranked,
            turned_square,
            per_object,
        }
    }

    /// Maps of the prepared batch (and of earlier cascade rounds) -> ranked
    /// grasps; no further view is inferred.
    pub fn finish(&self, mut prepared: Prepared, maps: &GraspMaps) -> Result<Plan> {
        maps.check_matches(&prepared.batch)?;
        let start = Instant::now();
        let fresh = self.decode_round(&mut prepared, maps);
        prepared.decoded.extend(fresh);
        self.rank_decoded(prepared, maps, start)
    }

    /// [`Self::finish`] once every round so far is decoded (`prepared.decoded`);
    /// `maps` are the current round's, for the debug views.
    fn rank_decoded(&self, mut prepared: Prepared, maps: &GraspMaps, start: Instant) -> Result<Plan> {
        let candidates = std::mem::take(&mut prepared.decoded);
        let mut verdicts = std::mem::take(&mut prepared.verdicts);
        let Vetted {
            ranked,
            turned_square,
            per_object,
        } = self.vet_and_rank(
            &prepared,
            candidates,
            &prepared.options,
            self.config.max_grasps_per_object,
            &mut verdicts,
        );
        let mut debug_maps = std::collections::HashMap::new();
        if prepared.options.keep_views {
            for (entries, maps) in prepared.rounds_so_far(maps) {
                let per_view = 4 * maps.size_px * maps.size_px;
                for (row, &entry) in entries.iter().enumerate() {
                    debug_maps.insert(entry, maps.data[row * per_view..(row + 1) * per_view].to_vec());
                }
            }
        }
        let Prepared {
            objects,
            table,
            obstacles: (obstacles, obstacles_dropped),
            options,
            mut timings,
            ..
        } = prepared;
        let count = |why: RankedLast| ranked.deferred.iter().filter(|&&d| d == why).count();
        let total = |f: fn(&ObjectRefusals) -> usize| per_object.iter().map(f).sum::<usize>();
        let refusals = Refusals {
            table: total(|r| r.table),
            own_object: total(|r| r.own_points),
            neighbour: total(|r| r.neighbour),
        };
        let outside_approach_cone = total(|r| r.outside_approach_cone);
        let out_of_reach = total(|r| r.out_of_reach);
        let mut debug_views = Vec::new();
        if options.keep_views {
            for (object_index, o) in objects.iter().enumerate() {
                for (v, view) in o.views.iter().enumerate() {
                    debug_views.push(DebugView {
                        object_id: o.object.id,
                        view: view.clone(),
                        maps: debug_maps.remove(&(object_index, v)),
                    });
                }
            }
        }
        timings.decode += start.elapsed();
        Ok(Plan {
            grasps: ranked.grasps,
            refused_for_collision: ranked.refused,
            refusals,
            ranked_after_turned_away: count(RankedLast::TurnedAway),
            ranked_last_out_of_view: count(RankedLast::OutOfView),
            outside_approach_cone,
            out_of_reach,
            turned_square,
            objects: objects
                .into_iter()
                .zip(per_object)
                .map(|(o, refused)| DetectedObject {
                    // Decoding's counts, kept on the object round by round.
                    refused: ObjectRefusals {
                        too_wide: o.object.refused.too_wide,
                        no_pose: o.object.refused.no_pose,
                        ..refused
                    },
                    ..o.object
                })
                .collect(),
            table,
            obstacles,
            obstacles_dropped,
            timings,
            debug_views,
        })
    }

    /// The whole pipeline with `net` run in-process.
    pub fn plan(
        &self,
        scene: &SceneInput<'_>,
        options: &PlanOptions,
        net: &mut dyn GraspNet,
    ) -> Result<Plan> {
        if net.contract() != &self.contract {
            return Err(Error::Backend(format!(
                "network contract {:?} differs from the planner's {:?}",
                net.contract().model_version,
                self.contract.model_version
            )));
        }
        let mut prepared = self.prepare(scene, options)?;
        let mut inference = Duration::ZERO;
        loop {
            let start = Instant::now();
            let maps = if prepared.batch.len == 0 {
                GraspMaps {
                    size_px: prepared.batch.size_px,
                    len: 0,
                    data: Vec::new(),
                }
            } else {
                net.infer(&prepared.batch)?
            };
            inference += start.elapsed();
            prepared.set_inference_time(inference);
            match self.finish_or_cascade(prepared, maps)? {
                Finished::Plan(plan) => return Ok(*plan),
                Finished::More(next) => prepared = *next,
            }
        }
    }
}

/// Times consecutive stages: each lap is the time since the previous one.
struct Stopwatch(Instant);

impl Stopwatch {
    fn start() -> Self {
        Self(Instant::now())
    }

    /// Writes the time since the last lap (or the start) into `slot`.
    fn lap(&mut self, slot: &mut Duration) {
        let now = Instant::now();
        *slot = now - self.0;
        self.0 = now;
    }
}

/// The views of an object that may give a grasp within `cone`: a grasp
/// approaches along its view's direction, whatever turns the hand check
/// makes about that direction, so a view whose direction lies outside the
/// cone gives none that passes, and is not worth inferring. Every view when
/// there is no cone, or when none lies within it (the object is then
/// planned as without the cone, and its grasps are counted as outside it:
/// a reason for each).
fn views_within(cone: Option<&ApproachCone>, frame: &ObjectFrame, views: &[OrthoView]) -> Vec<usize> {
    let every = || (0..views.len()).collect();
    let Some(cone) = cone else {
        return every();
    };
    let rotation = frame.world_from_object.rotation.to_rotation_matrix();
    // A little leeway: the grasps' own check must be the one that refuses.
    let leeway = ApproachCone {
        half_angle_rad: (cone.half_angle_rad + 1e-6).min(std::f64::consts::PI),
        ..*cone
    };
    let within: Vec<usize> = (0..views.len())
        .filter(|&v| leeway.allows(&(rotation * views[v].object_from_view.column(2))))
        .collect();
    if within.is_empty() { every() } else { within }
}
