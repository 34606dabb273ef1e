//! The whole method, split where a server batches across requests:
//! [`Planner::prepare`] (frame -> views to infer), the network, and
//! [`Planner::finish`] (maps -> ranked grasps). [`Planner::plan`] chains them.

use std::time::{Duration, Instant};

use nalgebra::{Isometry3, Point3, Vector3};

use crate::decode::{
    Collision, DecodeConfig, Grasp, HandConfig, Obstacle, RankConfig, Ranked, Repairs, Verdict,
    ViewPlacement, contact_slopes, decode_view, deepen, fit_opening, hand_collision, hand_out_of_view,
    lever_arm_m, rank_grasps_scored, squaring_turn, turn_away,
};
use crate::error::{Error, Result};
use crate::geometry::Workspace;
use crate::gripper::Gripper;
use crate::infer::{GraspMaps, GraspNet, ModelContract, NORMALISATION_CUBE_V1, ViewBatch};
use crate::object::{ObjectFrame, object_frame};
use crate::segment::{
    ClusterConfig, ImagePoints, TableConfig, TablePlane, euclidean_clusters, fit_table, fixed_order,
    split_at_creases,
};
use crate::select::{ViewPolicy, select_views};
use crate::sensor::{
    BlockMask, FieldOfView, SensorInput, random_world_points, world_points, world_points_above,
};
use crate::view::{OrthoView, ViewAxis};

/// One sensor frame and where it was taken from.
#[derive(Debug, Clone, Copy)]
pub struct SceneInput<'a> {
    /// The depth image or cloud.
    pub sensor: SensorInput<'a>,
    /// Camera pose in the world (z up).
    pub world_from_camera: Isometry3<f64>,
    /// Only points inside this box are considered.
    pub workspace: Workspace,
}

/// Per-request choices.
#[derive(Debug, Clone, PartialEq)]
pub struct PlanOptions {
    /// The gripper to plan for.
    pub gripper: Gripper,
    /// At most this many grasps in the answer.
    pub max_grasps: usize,
    /// Grasps under this quality are dropped (tau).
    pub min_quality: f32,
    /// Which views go through the network.
    pub view_policy: ViewPolicy,
    /// Keep the rendered views and their maps in the plan (debugging).
    pub keep_views: bool,
    /// An object whose chosen views give no grasp that clears `min_quality`
    /// and the hand check goes on to its next view by entropy, until one
    /// does or its views run out ([`Planner::finish_or_cascade`]). Off: the
    /// paper's one pass over the policy's views.
    pub view_cascade: bool,
    /// Only grasps approaching within this cone are planned (the robot's
    /// reachable approaches); `None`: any.
    pub approach_cone: Option<ApproachCone>,
}

/// A cone of approach directions (world frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ApproachCone {
    /// The cone's axis (unit).
    pub axis: Vector3<f64>,
    /// Half its opening angle (rad), in (0, pi].
    pub half_angle_rad: f64,
}

impl ApproachCone {
    /// A cone around `axis` (any length > 0), checked.
    pub fn new(axis: Vector3<f64>, half_angle_rad: f64) -> Result<Self> {
        let norm = axis.norm();
        if !(norm.is_finite() && norm > 1e-9) {
            return Err(Error::invalid(
                "approach_cone.axis",
                format!("must be finite and non-zero, got {axis:?}"),
            ));
        }
        if !(half_angle_rad.is_finite() && half_angle_rad > 0.0 && half_angle_rad <= std::f64::consts::PI) {
            return Err(Error::invalid(
                "approach_cone.half_angle_rad",
                format!("must be in (0, pi], got {half_angle_rad}"),
            ));
        }
        Ok(Self {
            axis: axis / norm,
            half_angle_rad,
        })
    }

    /// True when `approach` (unit) lies within the cone.
    pub fn allows(&self, approach: &Vector3<f64>) -> bool {
        approach.dot(&self.axis) >= self.half_angle_rad.cos() - 1e-12
    }
}

impl Default for PlanOptions {
    fn default() -> Self {
        Self {
            gripper: Gripper::default(),
            max_grasps: 10,
            min_quality: 0.5,
            view_policy: ViewPolicy::Entropy,
            keep_views: false,
            view_cascade: true,
            approach_cone: None,
        }
    }
}

impl PlanOptions {
    /// Checks the gripper and the limits.
    pub fn validate(&self) -> Result<()> {
        self.gripper.validate()?;
        if !(self.min_quality.is_finite() && (0.0..=1.0).contains(&self.min_quality)) {
            return Err(Error::invalid(
                "min_quality",
                format!("must be in [0, 1], got {}", self.min_quality),
            ));
        }
        if self.max_grasps == 0 {
            return Err(Error::invalid("max_grasps", "must be at least 1"));
        }
        Ok(())
    }
}

/// Service-wide settings of the pipeline (not per request).
#[derive(Debug, Clone, PartialEq)]
pub struct PlannerConfig {
    /// Table stage.
    pub table: TableConfig,
    /// Clustering stage.
    pub cluster: ClusterConfig,
    /// Decoding stage.
    pub decode: DecodeConfig,
    /// The hand checked against the observed points before a grasp is kept.
    pub hand: HandConfig,
    /// Views rendered per object.
    pub views: Vec<ViewAxis>,
    /// At most this many grasps per object.
    pub max_grasps_per_object: usize,
}

impl Default for PlannerConfig {
    fn default() -> Self {
        Self {
            table: TableConfig::default(),
            cluster: ClusterConfig::default(),
            decode: DecodeConfig::default(),
            hand: HandConfig::default(),
            views: ViewAxis::ALL.to_vec(),
            max_grasps_per_object: 3,
        }
    }
}

/// Below this many usable random readings the table is fitted on all of them.
const MIN_RANDOM_POINTS_TO_FIT: usize = 256;

/// Wall time of each stage.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StageTimings {
    /// Frame -> random world points in the workspace (for the table fit).
    pub sensor: Duration,
    /// Table plane fit.
    pub table: Duration,
    /// Block mask, then world points above the table at full resolution.
    pub sensor_objects: Duration,
    /// Euclidean clustering, then the crease split.
    pub cluster: Duration,
    /// Object frames.
    pub frames: Duration,
    /// View rendering, with each view's entropy.
    pub views: Duration,
    /// View selection and batching (the entropy is summed during `views`).
    pub select: Duration,
    /// The network (as measured by whoever ran it).
    pub inference: Duration,
    /// Peaks -> grasps, ranking.
    pub decode: Duration,
}

impl StageTimings {
    /// Every stage except the network.
    pub fn without_inference(&self) -> Duration {
        self.sensor
            + self.table
            + self.sensor_objects
            + self.cluster
            + self.frames
            + self.views
            + self.select
            + self.decode
    }
}

/// A view's summary for the answer.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewReport {
    /// Which view.
    pub axis: ViewAxis,
    /// Its viewpoint entropy (bits).
    pub entropy: f64,
    /// Whether it went through the network.
    pub inferred: bool,
}

/// An object found in the frame.
#[derive(Debug, Clone, PartialEq)]
pub struct DetectedObject {
    /// Id, in the fixed cluster order (0-based).
    pub id: u32,
    /// Its gravity-aligned frame and extent.
    pub frame: ObjectFrame,
    /// Its views.
    pub views: Vec<ViewReport>,
    /// Its candidate grasps lost to the hand check or the approach cone,
    /// by cause (among those checked: ranking stops checking once the
    /// answer is full). An object without a grasp says why here.
    pub refused: ObjectRefusals,
}

/// One object's candidate grasps lost, by cause.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ObjectRefusals {
    /// The hand would hit the table.
    pub table: usize,
    /// The hand would hit another object.
    pub neighbour: usize,
    /// The hand would hit the object's own points (no opening re-fit passed).
    pub own_points: usize,
    /// The approach lay outside [`PlanOptions::approach_cone`].
    pub outside_approach_cone: usize,
}

/// A rendered view with its maps, when [`PlanOptions::keep_views`] is set.
#[derive(Debug, Clone, PartialEq)]
pub struct DebugView {
    /// The object.
    pub object_id: u32,
    /// The view.
    pub view: OrthoView,
    /// `4 x l x l` maps in the contract's order, if the view was inferred.
    pub maps: Option<Vec<f32>>,
}

/// Grasps the hand check refused, by what the hand would have hit (after
/// the opening re-fit, where one was tried: what the re-fitted hand hit).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Refusals {
    /// The table.
    pub table: usize,
    /// The grasp's own object (its opening could not be re-fitted).
    pub own_object: usize,
    /// Another object.
    pub neighbour: usize,
}

/// Why a grasp is ranked after those that passed the hand check as
/// planned, in the order such grasps come.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
enum RankedLast {
    /// Turned about the approach until the hand passed
    /// ([`HandConfig::neighbour_turns_deg`]).
    TurnedAway,
    /// Pads past the image border ([`HandConfig::out_of_view_last`]).
    OutOfView,
}

/// The answer for one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct Plan {
    /// Ranked grasps, best first.
    pub grasps: Vec<Grasp>,
    /// Grasps dropped because the hand would hit an observed point or the
    /// table ([`HandConfig`]).
    pub refused_for_collision: usize,
    /// The same by what the hand would have hit.
    pub refusals: Refusals,
    /// Grasps after every grasp that passed the hand check as planned
    /// because they were turned about their approach until the hand passed
    /// a neighbour, or its own object at every opening
    /// ([`HandConfig::neighbour_turns_deg`]); they come before the
    /// `ranked_last_out_of_view`.
    pub ranked_after_turned_away: usize,
    /// Grasps at the end of `grasps` because their pads reach past the
    /// image border ([`HandConfig::out_of_view_last`]).
    pub ranked_last_out_of_view: usize,
    /// Grasps dropped before ranking because their approach lay outside
    /// [`PlanOptions::approach_cone`].
    pub outside_approach_cone: usize,
    /// Grasps turned about their approach axis to square them to the
    /// surfaces their pads meet ([`HandConfig::square_turn_deg`]), among
    /// those checked.
    pub turned_square: usize,
    /// Every object found, by id.
    pub objects: Vec<DetectedObject>,
    /// The table the objects stand on.
    pub table: TablePlane,
    /// Stage timings.
    pub timings: StageTimings,
    /// Views and maps, when asked for.
    pub debug_views: Vec<DebugView>,
}

/// What stands on the table: [`Planner::segment`]'s answer.
#[derive(Debug, Clone, PartialEq)]
pub struct Segmentation {
    /// The table.
    pub table: TablePlane,
    /// The points above the table (world).
    pub points: Vec<[f32; 3]>,
    /// Each point's pixel (`v * width + u`) for a depth image; empty for a cloud.
    pub pixels: Vec<u32>,
    /// The objects, as indices into `points`, in the fixed order (object ids).
    pub clusters: Vec<Vec<u32>>,
}

struct PreparedObject {
    object: DetectedObject,
    views: Vec<OrthoView>,
    /// Its points in its own frame, for the hand check.
    points: Vec<[f32; 3]>,
}

/// A frame made ready for the network: its views, and what comes after.
pub struct Prepared {
    objects: Vec<PreparedObject>,
    table: TablePlane,
    /// Where the camera looked (depth images; a cloud has no border).
    view: Option<FieldOfView>,
    /// `(object index, view index)` of each batch entry.
    inferred: Vec<(usize, usize)>,
    batch: ViewBatch,
    /// Each object's views not inferred yet, best entropy first (the cascade's order).
    untried: Vec<Vec<usize>>,
    /// Earlier rounds of the cascade: their entries and maps.
    earlier: Vec<(usize, usize)>,
    earlier_maps: Vec<f32>,
    /// Objects with a grasp that clears the hand check in an earlier round.
    covered: Vec<bool>,
    options: PlanOptions,
    timings: StageTimings,
}

/// The hand check's and the ranking's answer over the views inferred so far.
struct Vetted {
    ranked: Ranked<RankedLast>,
    turned_square: usize,
    /// What each object's candidates were lost to; the plan's totals are their sums.
    per_object: Vec<ObjectRefusals>,
}

impl Prepared {
    /// The `(object, view)` entries and maps of earlier cascade rounds,
    /// followed by this round's (`maps`).
    fn rounds_so_far(&self, maps: &GraspMaps) -> (Vec<(usize, usize)>, GraspMaps) {
        let entries = self.earlier.iter().chain(&self.inferred).copied().collect();
        let mut data = Vec::with_capacity(self.earlier_maps.len() + maps.data.len());
        data.extend_from_slice(&self.earlier_maps);
        data.extend_from_slice(&maps.data);
        let all = GraspMaps {
            size_px: maps.size_px,
            len: self.earlier.len() + maps.len,
            data,
        };
        (entries, all)
    }
}

/// The views not chosen, by entropy, highest first (ties: the earlier view).
fn cascade_order(entropies: &[f64], chosen: &[usize]) -> Vec<usize> {
    let mut rest: Vec<usize> = (0..entropies.len()).filter(|v| !chosen.contains(v)).collect();
    rest.sort_by(|&a, &b| entropies[b].total_cmp(&entropies[a]).then(a.cmp(&b)));
    rest
}

/// What [`Planner::finish_or_cascade`] gives: the plan, or more views to
/// run through the network first (the next round of the cascade).
pub enum Finished {
    /// Every object has a grasp, or no view is left to try.
    Plan(Box<Plan>),
    /// Run `Prepared::batch` through the network and finish again.
    More(Box<Prepared>),
}

impl Prepared {
    /// The views to run through the network, in batch order.
    pub fn batch(&self) -> &ViewBatch {
        &self.batch
    }

    /// Objects found so far.
    pub fn object_count(&self) -> usize {
        self.objects.len()
    }

    /// Records how long the network took (for the timings in the plan).
    pub fn set_inference_time(&mut self, elapsed: Duration) {
        self.timings.inference = elapsed;
    }
}

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
    /// for a depth image): the stages before the object frames.
    pub fn segment(&self, scene: &SceneInput<'_>) -> Result<Segmentation> {
        self.segment_timed(scene, &mut StageTimings::default())
    }

    fn segment_timed(&self, scene: &SceneInput<'_>, timings: &mut StageTimings) -> Result<Segmentation> {
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
        let above = world_points_above(sensor, pose, workspace, &half_space, near.as_ref())?;
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
        } = self.segment_timed(scene, &mut timings)?;
        let mut clock = Stopwatch::start();

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
            let chosen = select_views(options.view_policy, &self.config.views, &entropies, id);
            for &v in &chosen {
                batch.push(&views[v].image);
                inferred.push((index, v));
            }
            untried.push(cascade_order(&entropies, &chosen));
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
            view,
            inferred,
            batch,
            untried,
            earlier: Vec::new(),
            earlier_maps: Vec::new(),
            options: options.clone(),
            timings,
        })
    }

    /// Maps of the prepared batch -> ranked grasps, or, with
    /// [`PlanOptions::view_cascade`], the next views of the objects that have
    /// no grasp yet (clearing `min_quality` and the hand check) while any
    /// such object has a view left. Every round's maps count in the plan.
    pub fn finish_or_cascade(&self, mut prepared: Prepared, maps: &GraspMaps) -> Result<Finished> {
        maps.check_matches(&prepared.batch)?;
        if prepared.options.view_cascade && prepared.untried.iter().any(|u| !u.is_empty()) {
            let start = Instant::now();
            // Whether an object has a grasp that passes depends on its own
            // views alone, and earlier rounds' views are already counted:
            // only this round's views are decoded to update the cover.
            let newly = self.objects_with_grasps(&prepared, &prepared.inferred, maps);
            for (covered, newly) in prepared.covered.iter_mut().zip(newly) {
                *covered |= newly;
            }
            let (entries, all) = prepared.rounds_so_far(maps);
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
                prepared.earlier = entries;
                prepared.earlier_maps = all.data;
                prepared.inferred = next;
                prepared.batch = batch;
                return Ok(Finished::More(Box::new(prepared)));
            }
        }
        self.finish(prepared, maps)
            .map(|plan| Finished::Plan(Box::new(plan)))
    }

    /// Which objects have at least one grasp that clears `min_quality` and
    /// the hand check in the maps so far.
    fn objects_with_grasps(
        &self,
        prepared: &Prepared,
        entries: &[(usize, usize)],
        maps: &GraspMaps,
    ) -> Vec<bool> {
        let options = PlanOptions {
            max_grasps: usize::MAX,
            keep_views: false,
            ..prepared.options.clone()
        };
        // One grasp per object answers the question: the check stops there.
        let vetted = self.decode_and_rank(prepared, entries, maps, &options, 1);
        let mut covered = vec![false; prepared.objects.len()];
        for g in &vetted.ranked.grasps {
            if let Some(i) = prepared.objects.iter().position(|o| o.object.id == g.object_id) {
                covered[i] = true;
            }
        }
        covered
    }

    /// Decodes every inferred view (`entries`, rows of `maps`), checks the
    /// hand and ranks: the grasps, and what the check refused, deferred or turned.
    fn decode_and_rank(
        &self,
        prepared: &Prepared,
        entries: &[(usize, usize)],
        maps: &GraspMaps,
        options: &PlanOptions,
        max_per_object: usize,
    ) -> Vetted {
        let (objects, table, view) = (&prepared.objects, &prepared.table, &prepared.view);
        let mut grasps = Vec::new();
        for (batch_index, &(object, view)) in entries.iter().enumerate() {
            let o = &objects[object];
            let placement = ViewPlacement {
                view: &o.views[view],
                world_from_object: &o.object.frame.world_from_object,
                object_id: o.object.id,
            };
            grasps.extend(decode_view(
                &placement,
                maps,
                batch_index,
                &self.contract,
                &options.gripper,
                table,
                options.min_quality,
                &self.config.decode,
            ));
        }
        // Approaches the robot cannot take: dropped before anything else.
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
                vet(g, own, &vetting, &mut per_object, &mut turned_square)
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
    pub fn finish(&self, prepared: Prepared, maps: &GraspMaps) -> Result<Plan> {
        maps.check_matches(&prepared.batch)?;
        let start = Instant::now();
        let (inferred, maps) = prepared.rounds_so_far(maps);
        let Vetted {
            ranked,
            turned_square,
            per_object,
        } = self.decode_and_rank(
            &prepared,
            &inferred,
            &maps,
            &prepared.options,
            self.config.max_grasps_per_object,
        );
        let Prepared {
            objects,
            table,
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
        let mut debug_views = Vec::new();
        if options.keep_views {
            let per_view = 4 * maps.size_px * maps.size_px;
            for (object_index, o) in objects.iter().enumerate() {
                for (v, view) in o.views.iter().enumerate() {
                    let maps = inferred
                        .iter()
                        .position(|&e| e == (object_index, v))
                        .map(|b| maps.data[b * per_view..(b + 1) * per_view].to_vec());
                    debug_views.push(DebugView {
                        object_id: o.object.id,
                        view: view.clone(),
                        maps,
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
            turned_square,
            objects: objects
                .into_iter()
                .zip(per_object)
                .map(|(o, refused)| DetectedObject { refused, ..o.object })
                .collect(),
            table,
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
            match self.finish_or_cascade(prepared, &maps)? {
                Finished::Plan(plan) => return Ok(*plan),
                Finished::More(next) => prepared = *next,
            }
        }
    }
}

/// What the hand check of one answer's grasps looks at ([`vet`]).
struct Vetting<'a> {
    hand: &'a HandConfig,
    gripper: &'a Gripper,
    table: &'a TablePlane,
    obstacles: &'a [Obstacle<'a>],
    /// The camera's field of view (depth frames).
    view: Option<&'a FieldOfView>,
    table_clearance_m: f64,
}

/// One grasp through the hand check, in rank order: accepted as planned or
/// repaired (opening re-fitted, squared, deepened), deferred (turned away
/// from what it would hit, or pads out of view), or refused, its cause
/// counted in `per_object[own]`. `own`: the grasp's object among
/// `v.obstacles`.
fn vet(
    g: Grasp,
    own: Option<usize>,
    v: &Vetting<'_>,
    per_object: &mut [ObjectRefusals],
    turned_square: &mut usize,
) -> Verdict<RankedLast> {
    let hand = v.hand;
    let hit = |pose: &Isometry3<f64>, width: f64| {
        hand_collision(pose, width, v.gripper, hand, v.table, v.obstacles, own)
    };
    let mut refuse = |c: Collision| {
        let mut unknown = ObjectRefusals::default();
        let mine = own.map_or(&mut unknown, |i| &mut per_object[i]);
        match c {
            Collision::Table => mine.table += 1,
            Collision::Object(i) if Some(i) == own => mine.own_points += 1,
            Collision::Object(_) => mine.neighbour += 1,
        }
        Verdict::Refuse
    };
    // The check as planned: passed (no new pose), or what the
    // hand hits. Pads on its own object: open to what was seen
    // of it, and check again.
    let checked = match hit(&g.world_from_grasp, g.width_m) {
        None => Ok(None),
        Some(first @ Collision::Object(i)) if hand.fit_opening && Some(i) == own => {
            match fit_opening(&g.world_from_grasp, g.width_m, v.gripper, hand, &v.obstacles[i]) {
                None => Err(first),
                Some((pose, width)) => hit(&pose, width).map_or(Ok(Some((pose, width))), Err),
            }
        }
        Some(c) => Err(c),
    };
    // A hand that would hit a neighbour, or its own object at
    // every opening: turned about the approach if a turn passes,
    // ranked after the grasps as planned. Own-object turns
    // cleared 6 more of 308 train-pool objects
    // (docs/experiments/2026-11-28-ranking-and-candidates.md).
    let (repaired, turned_away) = match checked {
        Ok(repaired) => (repaired, false),
        Err(c) => {
            let turned = match c {
                Collision::Object(_) => own.and_then(|j| {
                    turn_away(
                        &g.world_from_grasp,
                        g.width_m,
                        v.gripper,
                        hand,
                        &v.obstacles[j],
                        |pose, width| hit(pose, width).is_none(),
                    )
                }),
                _ => None,
            };
            match turned {
                Some(turned) => (Some(turned), true),
                None => return refuse(c),
            }
        }
    };
    let mut g = match repaired {
        Some((world_from_grasp, width_m)) => Grasp {
            world_from_grasp,
            width_m,
            ..g
        },
        None => g,
    };
    g.repairs.turned_away = turned_away;
    g.repairs.refit = repaired.is_some() && !turned_away;
    // Square the grasp to the surfaces its pads would meet, as
    // seen, when the turned grasp passes the check too: of the
    // grasps tried in physics outside the labels' friction cone,
    // two in five were within 10 degrees of one inside
    // (sim/README.md).
    let turn = own.filter(|_| hand.enabled).and_then(|i| {
        let slopes = contact_slopes(&g.world_from_grasp, g.width_m, v.gripper, hand, &v.obstacles[i]);
        squaring_turn(slopes, hand)
    });
    let turned = turn
        .map(|t| g.world_from_grasp * nalgebra::UnitQuaternion::from_axis_angle(&Vector3::z_axis(), t))
        .filter(|pose| hit(pose, g.width_m).is_none());
    let g = match turned {
        Some(world_from_grasp) => {
            *turned_square += 1;
            Grasp {
                world_from_grasp,
                repairs: Repairs {
                    squared: true,
                    ..g.repairs
                },
                ..g
            }
        }
        None => g,
    };
    // Deeper where the hand and the table allow: fingertips
    // that stop above the middle of a round object let it slip.
    let deeper = hand.enabled.then(|| {
        deepen(
            &g.world_from_grasp,
            g.width_m,
            v.gripper,
            hand,
            v.table,
            v.table_clearance_m,
            |pose| hit(pose, g.width_m).is_none(),
        )
    });
    let mut g = match deeper.flatten() {
        Some(world_from_grasp) => Grasp {
            world_from_grasp,
            repairs: Repairs {
                deepened: true,
                ..g.repairs
            },
            ..g
        },
        None => g,
    };
    // Pads past the image border: maybe onto the part of the
    // object never seen. Tried last, not refused: the object may
    // have no other grasp.
    let unseen = v.view.is_some_and(|fov| {
        hand.enabled
            && hand.out_of_view_last
            && hand_out_of_view(&g.world_from_grasp, g.width_m, v.gripper, hand, fov)
    });
    g.repairs.out_of_view = unseen;
    if unseen {
        Verdict::Defer(g, RankedLast::OutOfView)
    } else if turned_away {
        Verdict::Defer(g, RankedLast::TurnedAway)
    } else {
        Verdict::Accept(g)
    }
}

/// World-frame approach direction of a grasp (its +z axis).
pub fn approach_of(grasp: &Grasp) -> Vector3<f64> {
    grasp.world_from_grasp.rotation * Vector3::z()
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
