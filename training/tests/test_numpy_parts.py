"""Tests of the numpy-only parts: dataset reader, augmentation, metric.

    python3 -m unittest discover -s training/tests -v
"""

import json
import os
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

from mvgrasp_train import attempt_views, augment, dataset, evaluate_onnx, metric, pack, physics, physics_score, refusals, repeatability  # noqa: E402


def line_view(l, u0, v0, phi, half):
    """A view with a bar of surface along angle phi through (u0, v0), its maps painted on it."""
    view = np.zeros((1, l, l), np.float32)
    maps = np.zeros((4, l, l), np.float32)
    for t in np.linspace(-half, half, 4 * half + 1):
        u, v = int(round(u0 + t * np.cos(phi))), int(round(v0 + t * np.sin(phi)))
        view[0, v, u] = 0.6
        maps[:, v, u] = [1.0, np.cos(2 * phi), np.sin(2 * phi), 0.3]
    return view, maps


def angle_of(maps, u, v):
    return 0.5 * np.arctan2(maps[2, v, u], maps[1, v, u])


def turned_bars(l=32):
    """(phi, k, (view, maps)): a bar through (14, 17) at three angles, under each of the 8 symmetries."""
    for phi in (0.3, -1.0, 1.2):
        view, maps = line_view(l, 14, 17, phi, 6)
        for k in range(8):
            yield phi, k, augment.symmetry(view, maps, k)


class Augmentation(unittest.TestCase):
    def test_symmetries_move_pixels_and_angles_together(self):
        for phi, k, (v2, m2) in turned_bars():
            # The painted bar still runs along the angle its pixels now carry.
            vs, us = np.nonzero(m2[0])
            angles = {round(float(angle_of(m2, u, v)), 6) for u, v in zip(us, vs)}
            self.assertEqual(len(angles), 1)
            a = angles.pop()
            pts = np.stack([us, vs], 1).astype(float)
            centred = pts - pts.mean(0)
            direction = np.linalg.svd(centred)[2][0]
            self.assertLess(metric.angle_diff(np.arctan2(direction[1], direction[0]), a), 0.1, (phi, k))
            np.testing.assert_array_equal(v2[0] > 0, m2[0] > 0)

    def test_rescale_scales_openings_and_keeps_the_centre(self):
        view, maps = line_view(33, 16, 16, 0.0, 8)
        v2, m2 = augment.rescale(view, maps, 1.1)
        self.assertAlmostEqual(float(m2[3, 16, 16]), 0.33, places=5)
        self.assertGreater(int((v2 > 0).sum()), int((view > 0).sum()))
        v3, _ = augment.rescale(view, maps, 0.9)
        self.assertLess(int((v3 > 0).sum()), int((view > 0).sum()))

    def test_corruption_touches_only_the_surface(self):
        rng = np.random.default_rng(1)
        view, _ = line_view(32, 16, 16, 0.5, 10)
        for _ in range(20):
            v2 = augment.corrupt(view, rng, dropout=0.2, clip_share=1.0)
            self.assertTrue(np.all(v2[view == 0] == 0))
            self.assertTrue(np.all((v2 >= 0) & (v2 <= 1)))
        self.assertFalse(np.array_equal(v2, view))


def standing_view(l=24):
    """A view of something standing on the table: a full bottom row, and a
    mark left of the centre above it, quality painted on both."""
    view = np.zeros((1, l, l), np.float32)
    view[0, l - 1, :] = 0.5
    view[0, l // 2, 3] = 0.7
    maps = np.zeros((4, l, l), np.float32)
    maps[:, view[0] > 0] = np.array([1.0, 1.0, 0.0, 0.3], np.float32)[:, None]
    return view, maps


class GravitySymmetries(unittest.TestCase):
    def test_front_and_side_views_keep_the_table_below_top_views_turn(self):
        view, maps = standing_view()
        for name, mode, keeps_table in (("front", "gravity", True), ("side", "gravity", True),
                                        ("top", "gravity", False), ("front", "all", False)):
            rng = np.random.default_rng(3)
            bottoms, marks = set(), set()
            for _ in range(64):
                _, m = augment.augment(view, maps, rng, scale=0, mask=augment.symmetry_mask(name, mode))
                rows, cols = np.nonzero(m[0])
                bottoms.add(bool(np.all(m[0, -1] > 0)))
                marks.add(tuple(sorted(set(zip(rows.tolist(), cols.tolist())) - {(23, c) for c in range(24)})))
            if keeps_table:
                self.assertEqual(bottoms, {True}, (name, mode))
                # Both the view and its left-right mirror are drawn.
                self.assertEqual(marks, {((12, 3),), ((12, 20),)}, (name, mode))
            else:
                self.assertEqual(bottoms, {True, False}, (name, mode))

    def test_the_mask_leaves_the_random_draws_alone(self):
        view, maps = standing_view()
        after = []
        for mask in (augment.ALL_SYMMETRIES, augment.KEEP_DOWN):
            rng = np.random.default_rng(5)
            for _ in range(10):
                augment.augment(view, maps, rng, mask=mask)
            after.append(rng.random())
        self.assertEqual(after[0], after[1])

    def test_masks_by_view_and_mode(self):
        self.assertEqual(augment.symmetry_mask("top", "gravity"), 7)
        self.assertEqual(augment.symmetry_mask("front", "gravity"), 1)
        self.assertEqual(augment.symmetry_mask("side", "gravity"), 1)
        self.assertEqual(augment.symmetry_mask("side", "all"), 7)
        self.assertEqual(augment.symmetry_mask(None, "all"), 7)
        with self.assertRaisesRegex(ValueError, "direction of gravity is unknown"):
            augment.symmetry_mask(None, "gravity")
        with self.assertRaisesRegex(ValueError, "not one of"):
            augment.symmetry_mask("top", "upright")

    def test_attempts_turn_each_by_its_own_symmetry(self):
        rng = np.random.default_rng(4)
        views = rng.uniform(0, 1, (6, 9, 9)).astype(np.float32)
        pixels = rng.integers(0, 9, (6, 2))
        ks = np.array([0, 5, 1, 5, 7, 1])
        v, p = physics.symmetry_each(views, pixels, ks)
        for n, k in enumerate(ks):
            want_v, want_p = physics.symmetry(views[n:n + 1], pixels[n:n + 1], int(k))
            np.testing.assert_array_equal(v[n], want_v[0])
            np.testing.assert_array_equal(p[n], want_p[0])


class Metric(unittest.TestCase):
    def test_iou_of_known_rectangles(self):
        a = metric.rectangle(10, 10, 0.0, 10, 4)
        self.assertAlmostEqual(metric.iou(a, a), 1.0)
        shifted = metric.rectangle(15, 10, 0.0, 10, 4)  # half overlap: 20 / (40 + 40 - 20)
        self.assertAlmostEqual(metric.iou(a, shifted), 1 / 3)
        crossed = metric.rectangle(10, 10, np.pi / 2, 10, 4)  # 16 / (80 - 16)
        self.assertAlmostEqual(metric.iou(a, crossed), 0.25)
        self.assertEqual(metric.iou(a, metric.rectangle(40, 40, 0.0, 10, 4)), 0.0)

    def test_paired_views_count_discordant_views_only(self):
        first = [True, True, False, None, False, True]
        other = [True, False, True, None, True, True]
        only_it, only_first, p = metric.paired_views(first, other)
        self.assertEqual((only_it, only_first), (2, 1))  # views 2 and 4 / view 1; view 3 has no positives
        self.assertAlmostEqual(p, 1.0)
        self.assertEqual(metric.paired_views(first, first), (0, 0, 1.0))
        self.assertAlmostEqual(metric.sign_test(0, 5), 2 / 32)
        self.assertAlmostEqual(metric.sign_test(8, 2), 2 * 56 / 1024)
        with self.assertRaises(ValueError):
            metric.paired_views(first, other[:-1])

    def test_angles_are_modulo_pi(self):
        self.assertAlmostEqual(float(metric.angle_diff(np.pi / 2 - 0.1, -np.pi / 2 + 0.1)), 0.2)
        self.assertAlmostEqual(float(metric.angle_diff(0.0, np.pi / 2)), np.pi / 2)

    def test_a_grasp_is_correct_only_near_a_truth_in_angle_and_overlap(self):
        truth = np.array([[20, 20, 0.2, 0.05, 0.9]], np.float32)
        pixel, pad = 0.0025, 0.027
        self.assertTrue(metric.grasp_correct((20, 20, 0.2, 0.05), truth, pixel, pad))
        self.assertTrue(metric.grasp_correct((21, 20, 0.6, 0.055), truth, pixel, pad))
        self.assertFalse(metric.grasp_correct((20, 20, 0.2 + np.deg2rad(31), 0.05), truth, pixel, pad))
        self.assertFalse(metric.grasp_correct((40, 20, 0.2, 0.05), truth, pixel, pad))
        self.assertFalse(metric.grasp_correct((20, 20, 0.2, 0.05), truth[:0], pixel, pad))
        # A stricter angle tolerance: 10 degrees off passes at 30 and 12, not at 7.5.
        off = (20, 20, 0.2 + np.deg2rad(10), 0.05)
        self.assertTrue(metric.grasp_correct(off, truth, pixel, pad))
        self.assertTrue(metric.grasp_correct(off, truth, pixel, pad, angle_limit_deg=12))
        self.assertFalse(metric.grasp_correct(off, truth, pixel, pad, angle_limit_deg=7.5))

    def test_decode_reads_the_argmax_pixel(self):
        maps = np.zeros((2, 4, 8, 8), np.float32)
        maps[0, :, 3, 5] = [0.9, 0.0, 1.0, 0.25]  # phi = pi/4
        maps[1, :, 6, 1] = [0.4, -1.0, 0.0, 0.5]  # phi = pi/2
        u, v, phi, w, q = metric.decode(maps)
        np.testing.assert_array_equal(u, [5, 1])
        np.testing.assert_array_equal(v, [3, 6])
        self.assertAlmostEqual(float(phi[0]), np.pi / 4, places=6)
        self.assertAlmostEqual(abs(float(phi[1])), np.pi / 2, places=6)
        np.testing.assert_allclose(q, [0.9, 0.4])

    def test_the_planner_s_smoothing_prefers_a_broad_peak_to_a_lone_spike(self):
        maps = np.zeros((1, 4, 16, 16), np.float32)
        maps[0, 0, 3, 3] = 0.9  # one pixel
        maps[0, 0, 8:13, 8:13] = 0.7  # a 5 x 5 plateau centred at (u, v) = (10, 10)
        maps[0, 1] = 1.0
        self.assertEqual((int(metric.decode(maps)[0][0]), int(metric.decode(maps)[1][0])), (3, 3))
        smoothed = metric.smooth_quality(maps, 1.0)
        u, v, _, _, q = metric.decode(smoothed)
        self.assertEqual((int(u[0]), int(v[0])), (10, 10))
        self.assertLess(float(q[0]), 0.7)
        np.testing.assert_array_equal(smoothed[:, 1:], maps[:, 1:])
        # Both lie 3 sigma inside the map: no mass is lost. Sigma 0 is the raw map.
        self.assertAlmostEqual(float(smoothed[0, 0].sum()), 0.9 + 0.7 * 25, places=4)
        self.assertIs(metric.smooth_quality(maps, 0.0), maps)

    def test_an_object_acts_on_its_best_view_and_only_above_the_threshold(self):
        # Object a: its top view is right at 0.3, its side view (no positives) peaks at 0.6 and wins.
        # Object b: right on its front view at 0.5, wrong on its top view at 0.2: right.
        # Object c: no positives anywhere, peaks at 0.15: a false alarm at 0.1, none at 0.2.
        # Object d: right at 0.05 only: right at any quality, not picked at 0.1.
        ok = [True, None, False, True, None, None, True]
        quality = [0.3, 0.6, 0.2, 0.5, 0.15, 0.05, 0.05]
        instances = ["a", "a", "b", "b", "c", "c", "d"]
        r = metric.object_picks(ok, quality, instances, threshold=0.1)
        self.assertEqual((r["objects_with_positives"], r["objects_without_positives"]), (3, 1))
        self.assertAlmostEqual(r["accuracy"], 2 / 3)  # b and d
        self.assertAlmostEqual(r["picked"], 1 / 3)  # b only: d is below 0.1
        self.assertEqual(r["attempts"], 3)  # a, b, c
        self.assertAlmostEqual(r["attempt_precision"], 1 / 3)
        self.assertEqual(r["false_alarm_rate"], 1.0)
        # a is the one miss: its winning view has no positives, and its top view was right.
        self.assertEqual((r["wrong_view"], r["another_view_right"]), (1, 1))
        r = metric.object_picks(ok, quality, instances, threshold=0.2)
        self.assertEqual((r["attempts"], r["false_alarm_rate"]), (2, 0.0))
        # Lowering a's side view below its top view makes a right.
        quality[1] = 0.25
        r = metric.object_picks(ok, quality, instances)
        self.assertEqual((r["accuracy"], r["wrong_view"], r["another_view_right"]), (1.0, 0, 0))
        # No object at all: shares are nan, not a division by zero.
        empty = metric.object_picks([], [], [])
        self.assertTrue(np.isnan(empty["accuracy"]) and np.isnan(empty["false_alarm_rate"]))


def write_dataset(root, l=8):
    """A two-shard dataset in `sim datagen`'s format, written by hand."""
    contract = {"input_size_px": l, "pixel_size_m": 0.0025, "width_scale_m": 0.2,
                "normalisation": "cube-v1", "outputs": ["quality", "cos2phi", "sin2phi", "width"]}
    shards, meta_all, views_total, positives_total = [], [], 0, 0
    for s, views_in_shard in enumerate([2, 1]):
        name = f"shard_{s:05}"
        os.makedirs(os.path.join(root, name))
        views = np.zeros((views_in_shard, 1, l, l), np.float32)
        maps = np.zeros((views_in_shard, 4, l, l), np.float32)
        grasps = []
        for i in range(views_in_shard):
            views[i, 0, 2:6, 2:6] = 0.5
            if (s, i) != (0, 1):
                maps[i, :, 4, 3] = [0.8, 1.0, 0.0, 0.25]
                grasps.append([i, 3, 4, 0.0, 0.05, 0.8])
        np.save(os.path.join(root, name, "views.npy"), views)
        np.save(os.path.join(root, name, "maps.npy"), maps)
        np.save(os.path.join(root, name, "grasps.npy"), np.array(grasps, np.float32).reshape(-1, 6))
        with open(os.path.join(root, name, "meta.jsonl"), "w") as f:
            for i in range(views_in_shard):
                positives = int(any(g[0] == i for g in grasps))
                positives_total += positives > 0
                m = {"instance": f"{s}:{i}", "view": "top", "positives": positives, "family": "box"}
                meta_all.append(m)
                f.write(json.dumps(m) + "\n")
        shards.append(name)
        views_total += views_in_shard
    manifest = {"format_version": 2, "contract": contract, "shards": shards, "views": views_total,
                "views_with_positives": positives_total,
                "gripper": {"max_width_m": 0.14, "pad_width_m": 0.027}}
    with open(os.path.join(root, "manifest.json"), "w") as f:
        json.dump(manifest, f)


class Reader(unittest.TestCase):
    def test_reads_shards_with_global_grasp_indices_and_checks_them(self):
        with tempfile.TemporaryDirectory() as root:
            write_dataset(root)
            ds = dataset.load(root)
            self.assertEqual(ds.views.shape, (3, 1, 8, 8))
            self.assertEqual(dataset.check(ds), [])
            self.assertEqual(len(ds.grasps_of(0)), 1)
            self.assertEqual(len(ds.grasps_of(1)), 0)
            np.testing.assert_array_equal(ds.grasps_of(2)[:, :2], [[3, 4]])
            # The metric on the targets themselves: every view with a positive is a hit.
            result = metric.evaluate(ds.maps, ds, [0, 1, 2])
            self.assertEqual(result["accuracy"], 1.0)
            self.assertEqual(result["views_without_positives"], 1)
            # One view per instance here: the objects' picks are the views'.
            self.assertEqual((result["objects"]["objects_with_positives"], result["objects"]["accuracy"]), (2, 1.0))
            # The targets' peaks: 0.8 on both views with positives, 0 on the one without.
            self.assertAlmostEqual(result["median_peak_with_positives"], 0.8, places=6)
            self.assertEqual(result["median_peak_without_positives"], 0.0)
            # No scene_seed in this meta: each view is its own scene.
            self.assertEqual(result["scenes"]["objects_with_positives"], 2)
            # Views 0 and 2 of one scene are one scene; two frames of an episode
            # (sim eval --label-frames: `step`) are two.
            ds.meta[0]["scene_seed"] = ds.meta[2]["scene_seed"] = 7
            self.assertEqual(metric.evaluate(ds.maps, ds, [0, 1, 2])["scenes"]["objects_with_positives"], 1)
            ds.meta[0]["step"], ds.meta[2]["step"] = 0, 3
            self.assertEqual(metric.evaluate(ds.maps, ds, [0, 1, 2])["scenes"]["objects_with_positives"], 2)
            # The same seed and step in two scenarios (sim eval runs each from the same seeds): two scenes.
            ds.meta[2]["step"], ds.meta[0]["scenario"], ds.meta[2]["scenario"] = 0, "isolated", "pile"
            self.assertEqual(metric.evaluate(ds.maps, ds, [0, 1, 2])["scenes"]["objects_with_positives"], 2)
            ds.meta[2]["scenario"] = "isolated"
            self.assertEqual(metric.evaluate(ds.maps, ds, [0, 1, 2])["scenes"]["objects_with_positives"], 1)
            ds.meta[2]["step"] = 3
            keep = evaluate_onnx.view_filter(ds.meta, min_step=1)
            self.assertEqual([i for i in range(3) if keep(i)], [2])  # view 1 has no step: step 0
            self.assertEqual([i for i in range(3) if evaluate_onnx.view_filter(ds.meta)(i)], [0, 1, 2])
            del ds.meta[0]["step"], ds.meta[2]["step"], ds.meta[0]["scene_seed"], ds.meta[2]["scene_seed"]
            # View 0's best grasp turned 10 degrees: right at the paper's 30, wrong at 7.5.
            turned = np.array(ds.maps)
            y, x = np.unravel_index(np.argmax(turned[0, 0]), turned[0, 0].shape)
            phi = 0.5 * np.arctan2(turned[0, 2, y, x], turned[0, 1, y, x]) + np.deg2rad(10)
            turned[0, 1:3, y, x] = [np.cos(2 * phi), np.sin(2 * phi)]
            self.assertEqual(metric.evaluate(turned, ds, [0, 1, 2])["accuracy"], 1.0)
            self.assertEqual(metric.evaluate(turned, ds, [0, 1, 2], angle_limit_deg=7.5)["accuracy"], 0.5)
            # Refusal counts that do not add up to the candidates are caught.
            ds.meta[0].update(candidates=5, refused={"object: pad": 3, "no pose": 1})
            self.assertEqual(dataset.check(ds), [])
            ds.meta[0]["refused"]["no pose"] = 2
            self.assertTrue(any("refused" in p for p in dataset.check(ds)))
            ds.meta[0]["refused"]["no pose"] = 1
            # A painted pixel without its grasp row is caught.
            ds.maps[1, :, 1, 1] = [0.5, 1.0, 0.0, 0.2]
            self.assertTrue(any("painted" in p for p in dataset.check(ds)))

    def test_accuracy_per_family_and_the_missed_views(self):
        with tempfile.TemporaryDirectory() as root:
            write_dataset(root)
            ds = dataset.load(root)
            ds.meta[2]["family"] = "mug"
            pred = np.array(ds.maps)
            # View 2's best grasp turns 90 degrees on its only positive: a miss.
            pred[2, :, 4, 3] = [0.9, -1.0, 0.0, 0.25]
            self.assertEqual(metric.misses(pred, ds, [0, 1, 2]), [2])
            self.assertEqual(metric.misses(pred[[2, 0]], ds, [2, 0]), [0], "positions into the given indices")
            # Judgements the caller already has (`hits` at its own angle limit) are used as given.
            ok, _ = metric.hits(pred, ds, [0, 1, 2])
            self.assertEqual(metric.misses(pred, ds, [0, 1, 2], ok=ok), [2])
            self.assertEqual(metric.misses(pred, ds, [0, 1, 2], ok=[False, None, True]), [0])
            result = metric.evaluate(pred, ds, [0, 1, 2], by=("family", "scenario"))
            self.assertEqual(result["per_family"],
                             {"box": {"accuracy": 1.0, "views": 1}, "mug": {"accuracy": 0.0, "views": 1}})
            # Views without positives count in no group's accuracy, and a missing key is "?".
            self.assertEqual(result["per_scenario"], {"?": {"accuracy": 0.5, "views": 2}})
            # That miss is the heads' (on the positive, turned); a peak far off (and turned: the
            # rectangles of this 8 px view overlap wherever they are) is the placement's.
            kinds = metric.miss_kinds(pred, ds, [0, 1, 2])
            self.assertEqual((kinds["views_with_positives"], kinds["missed_far"], kinds["missed_heads"]), (2, 0, 1))
            self.assertEqual((kinds["median_positives_hit"], kinds["median_positives_missed"]), (1.0, 1.0))
            self.assertEqual(result["misses"], kinds, "evaluate reports the same counts from its own judgements")
            pred[2, :, 4, 3] = ds.maps[2, :, 4, 3]
            pred[2, :, 0, 7] = [0.95, -1.0, 0.0, 0.25]
            kinds = metric.miss_kinds(pred, ds, [0, 1, 2])
            self.assertEqual((kinds["missed_far"], kinds["missed_heads"]), (1, 0))
            pred[2, :, 0, 7] = 0.0
            self.assertEqual(metric.miss_kinds(pred, ds, [0, 1, 2])["median_positives_missed"], None)

    def test_rejects_another_format_version(self):
        with tempfile.TemporaryDirectory() as root:
            write_dataset(root)
            path = os.path.join(root, "manifest.json")
            with open(path) as f:
                manifest = json.load(f)
            manifest["format_version"] = 1
            with open(path, "w") as f:
                json.dump(manifest, f)
            with self.assertRaisesRegex(ValueError, "format_version 1"):
                dataset.load(root)

    def test_comma_separated_datasets_are_concatenated_with_shifted_grasp_indices(self):
        with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
            write_dataset(a)
            write_dataset(b)
            ds = dataset.load(f"{a},{b}")
            self.assertEqual(ds.views.shape, (6, 1, 8, 8))
            self.assertEqual(ds.manifest["views"], 6)
            self.assertEqual(ds.manifest["views_with_positives"], 4)
            self.assertEqual(dataset.check(ds), [])
            self.assertEqual([len(ds.grasps_of(i)) for i in range(6)], [1, 0, 1, 1, 0, 1])
            np.testing.assert_array_equal(ds.grasps_of(5)[:, :2], [[3, 4]])
            self.assertEqual(metric.evaluate(ds.maps, ds, range(6))["accuracy"], 1.0)

    def test_datasets_with_other_contracts_are_not_merged(self):
        with tempfile.TemporaryDirectory() as a, tempfile.TemporaryDirectory() as b:
            write_dataset(a)
            write_dataset(b, l=12)
            with self.assertRaisesRegex(ValueError, "contract"):
                dataset.load(f"{a},{b}")

    def test_split_keeps_instances_whole_and_is_about_80_20(self):
        meta = [{"instance": f"{i // 3}:0"} for i in range(3000)]
        train, held = dataset.split_by_instance(meta)
        self.assertFalse({meta[i]["instance"] for i in train} & {meta[i]["instance"] for i in held})
        self.assertAlmostEqual(len(held) / 3000, 0.2, delta=0.04)


    def test_the_evaluation_sample_takes_whole_objects(self):
        meta = [{"instance": f"s:{k // 3}"} for k in range(30)] + [{"instance": "lone"}]
        indices = list(range(31))
        picked = dataset.sample_objects(meta, indices, 7, np.random.default_rng(1))
        self.assertGreaterEqual(len(picked), 7)
        self.assertEqual(list(picked), sorted(picked))
        names = {meta[i]["instance"] for i in picked}
        # Every view of each object drawn, none of the rest; at most one object past 7 views.
        self.assertEqual(sorted(picked), sorted(i for i in indices if meta[i]["instance"] in names))
        self.assertLessEqual(len(names), 3 + 1)
        self.assertEqual(len(dataset.sample_objects(meta, indices, 0, np.random.default_rng(1))), 0)
        self.assertEqual(len(dataset.sample_objects(meta, indices, 1000, np.random.default_rng(1))), 31)
        # Only the given indices are drawn from.
        self.assertTrue(set(dataset.sample_objects(meta, [0, 1, 2, 30], 100, np.random.default_rng(0))) <= {0, 1, 2, 30})

    def test_evaluation_scores_the_held_out_split_every_view_or_the_training_split(self):
        meta = [{"instance": f"{i // 3}:0"} for i in range(300)]
        train, held = dataset.split_by_instance(meta)
        self.assertEqual(evaluate_onnx.scored_views(meta), held)
        self.assertEqual(evaluate_onnx.scored_views(meta, training_views=True), train)
        self.assertEqual(evaluate_onnx.scored_views(meta, all_views=True), list(range(300)))
        with self.assertRaises(SystemExit):
            evaluate_onnx.scored_views(meta, all_views=True, training_views=True)

    def test_the_flip_average_turns_the_maps_and_the_angles_back(self):
        def equivariant(views):
            # Quality the view itself; the angle along the view's gradient;
            # the width its size. Flipping the input flips these maps and
            # mirrors the angle, so the average over flips equals one pass.
            gy, gx = np.gradient(views[:, 0], axis=(1, 2))
            phi = np.arctan2(gy, gx)
            return np.stack([views[:, 0], np.cos(2 * phi), np.sin(2 * phi), np.hypot(gx, gy)], axis=1)

        views = np.random.default_rng(4).random((3, 1, 12, 12)).astype(np.float32)
        one = equivariant(views)
        self.assertGreater(np.abs(one[:, 2]).mean(), 0.3)  # the angles are not trivially 0
        self.assertLess(np.abs(evaluate_onnx.flip_average(equivariant, views) - one).max(), 1e-5)

        def leaning(views):  # prefers the left of every view: no flip keeps it
            maps = equivariant(views)
            maps[:, 0] = np.linspace(1.0, 0.0, views.shape[3])
            return maps

        averaged = evaluate_onnx.flip_average(leaning, views)
        self.assertLess(np.abs(averaged[:, 0] - 0.5).max(), 1e-6)

        # The mirror alone: as equivariant, as even left-right, and it keeps
        # what lies below (the table in a front view) where four flips lose it.
        self.assertLess(np.abs(evaluate_onnx.flip_average(equivariant, views, "mirror") - one).max(), 1e-5)
        self.assertLess(np.abs(evaluate_onnx.flip_average(leaning, views, "mirror")[:, 0] - 0.5).max(), 1e-6)

        def low(views):  # prefers the bottom of every view
            maps = equivariant(views)
            maps[:, 0] = np.linspace(0.0, 1.0, views.shape[2])[:, None]
            return maps

        np.testing.assert_allclose(evaluate_onnx.flip_average(low, views, "mirror")[:, 0], low(views)[:, 0])
        self.assertLess(np.abs(evaluate_onnx.flip_average(low, views)[:, 0] - 0.5).max(), 1e-6)


class Pack(unittest.TestCase):
    """pack.py: what travels to the GPU machine comes back as a dataset and
    attempt folders that train reads, in float16, the grasps derived from
    the maps."""

    def test_a_dataset_and_attempts_round_trip(self):
        with tempfile.TemporaryDirectory() as root:
            data, attempts, packed, out = (os.path.join(root, n) for n in ("d", "av", "pack", "out"))
            write_dataset(data)
            # A width the gripper just opens to: float16 must not round it past max_width_m.
            ds0 = dataset.load(data)
            maps = np.load(os.path.join(data, "shard_00000", "maps.npy"))
            maps[0, :, 4, 3] = [1 / 3, 0.6, 0.8, 0.7]
            np.save(os.path.join(data, "shard_00000", "maps.npy"), maps)
            write_attempts(attempts, [((1, 2), "ok"), ((3, 4), "slip during lift"), ((2, 2), "ok")],
                           alternatives=[False, True, False])
            pack.main(["pack", "--data", data, "--physics", attempts, "--own-only", "--out", packed])
            self.assertFalse(any(f == "grasps.npy" for _, _, fs in os.walk(packed) for f in fs))
            self.assertEqual(pack.unpack(packed, out), [("attempts", os.path.join(out, "av")),
                                                     ("dataset", os.path.join(out, "d"))])
            ds = dataset.load(os.path.join(out, "d"))
            self.assertEqual(dataset.check(ds), [])
            np.testing.assert_allclose(ds.views, ds0.views, atol=2.5e-4)
            self.assertLessEqual(ds.maps[0, 3, 4, 3], 0.7)
            self.assertAlmostEqual(float(ds.maps[0, 3, 4, 3]), 0.7, delta=5e-4)  # one float16 step down
            self.assertAlmostEqual(float(ds.maps[0, 0, 4, 3]), 1 / 3, delta=2.5e-4)
            # One grasp per painted pixel, the maps' angle (2 phi = atan2(0.8, 0.6)) and opening.
            g = ds.grasps_of(0)
            self.assertEqual(len(g), 1)
            np.testing.assert_allclose(g[0, :2], [3, 4])
            self.assertAlmostEqual(float(g[0, 2]), 0.5 * np.arctan2(0.8, 0.6), places=3)
            self.assertAlmostEqual(float(g[0, 3]), 0.7 * 0.2, delta=1e-4)
            self.assertEqual([m["positives"] for m in ds.meta], [1, 0, 1])
            self.assertEqual(dataset.split_by_instance(ds.meta), dataset.split_by_instance(ds0.meta))
            self.assertEqual(metric.evaluate(ds.maps, ds, [0, 1, 2])["accuracy"], 1.0)
            a = physics.load(os.path.join(out, "av"))
            np.testing.assert_array_equal(a.pixels, [[1, 2], [2, 2]])
            np.testing.assert_array_equal(a.views[:, 0, 0], [0.0, 2.0])
            with open(os.path.join(out, "av", "manifest.json")) as f:
                self.assertEqual(json.load(f)["attempts"], 2)

    def test_a_painted_quality_stays_painted_in_float16(self):
        maps = np.zeros((1, 4, 2, 2), np.float32)
        maps[0, :, 0, 0] = [1e-9, 1.0, 0.0, 0.1]
        half = pack.to_half(maps, 0, 3)
        self.assertGreater(float(half[0, 0, 0, 0]), 0)

    def test_refusals_say_why(self):
        with tempfile.TemporaryDirectory() as root:
            a, b = os.path.join(root, "a", "x"), os.path.join(root, "b", "x")
            write_dataset(a)
            write_dataset(b)
            with self.assertRaisesRegex(SystemExit, "repeat"):
                pack.main(["pack", "--data", f"{a},{b}", "--out", os.path.join(root, "p")])
            os.makedirs(os.path.join(root, "empty"))
            with self.assertRaisesRegex(SystemExit, "no packed folder"):
                pack.main(["unpack", os.path.join(root, "empty"), "--out", os.path.join(root, "o")])
            with self.assertRaisesRegex(SystemExit, "not a packed folder"):
                pack.main(["unpack", os.path.join(root, "a"), "--out", os.path.join(root, "o")])
            with self.assertRaisesRegex(SystemExit, "not a sim eval"):
                pack.main(["pack", "--physics", a, "--out", os.path.join(root, "q")])


class Refusals(unittest.TestCase):
    def test_shares_add_up_the_views_counts_largest_first(self):
        meta = [{"candidates": 10, "positives": 2, "refused": {"object: pad": 5, "no pose": 3}},
                {"candidates": 30, "positives": 0, "refused": {"over stroke": 20, "object: pad": 10}},
                {"candidates": 99, "positives": 99, "refused": {}}]
        candidates, parts = refusals.shares(meta, [0, 1])
        self.assertEqual(candidates, 40)
        self.assertEqual([k for k, _ in parts], ["positive", "over stroke", "object: pad", "no pose"])
        np.testing.assert_allclose([s for _, s in parts], [2 / 40, 20 / 40, 15 / 40, 3 / 40])
        self.assertAlmostEqual(sum(s for _, s in parts), 1.0)
        self.assertIn("2 views, 40 candidates: positive 5.0%, over stroke 50.0%", refusals.line("x", meta, [0, 1]))

    def test_data_without_refusal_counts_is_refused_with_a_reason(self):
        with tempfile.TemporaryDirectory() as root:
            write_dataset(root)
            with self.assertRaises(SystemExit) as e:
                refusals.main(["--data", root])
            self.assertIn("without refusal counts", str(e.exception))


def labelled_twice(n=6, l=24, k=5):
    """Two in-memory runs of the same n views: B is A turned by symmetry k, and B's last grasp moved off."""
    rng = np.random.default_rng(3)
    views, maps, grasps, meta = [], [], [], []
    for i in range(n):
        phi = float(rng.uniform(-1.5, 1.5))
        view, m = line_view(l, 11 + i % 3, 12, phi, 5)
        view[0, 6:18, 8:16] = np.maximum(view[0, 6:18, 8:16], 0.3)  # an uneven blob: symmetries differ
        view[0, 6:9, 8:10] = 0.9
        views.append(view)
        maps.append(m)
        grasps.append([i, 11 + i % 3, 12, phi, 0.04, 0.8 - 0.01 * i])
        grasps.append([i, 11 + i % 3, 12, phi + 0.7, 0.04, 0.1])  # a worse positive at another angle
        meta.append({"instance": f"{i}:0", "view": "top", "family": "box"})
    generator = {"scenes": n, "first_seed": 1, "scenarios": ["packed"], "families": ["box"], "noise": True,
                 "stride_px": 3, "angles": 8, "anneal_steps": 6, "label_salt": 0, "neighbours": True}
    manifest = {"format_version": 2, "data_version": "t", "generator": generator,
                "contract": {"input_size_px": l, "pixel_size_m": 0.0025, "width_scale_m": 0.2},
                "gripper": {"max_width_m": 0.14, "pad_width_m": 0.027}}
    a = dataset.Dataset(np.stack(views), np.stack(maps), np.array(grasps, np.float32), meta, manifest)
    turned = [augment.symmetry(v, m, k) for v, m in zip(views, maps)]
    g = np.array(grasps, np.float32)
    g[:, 1:4] = repeatability.move_grasps(g[:, 1:4], k, l)
    g[-2:, 1:3] = [[2, 2], [2, 2]]  # the last view's positives land elsewhere
    b_manifest = dict(manifest, generator=dict(generator, label_salt=7))
    b = dataset.Dataset(np.stack([t[0] for t in turned]), np.stack([t[1] for t in turned]), g, list(meta),
                        b_manifest)
    return a, b


class Repeatability(unittest.TestCase):
    def test_grasps_move_as_the_maps_do_under_every_symmetry(self):
        for phi, k, (_, m2) in turned_bars(l=32):
            (u, v, moved), = repeatability.move_grasps([[14, 17, phi]], k, 32)
            self.assertGreater(m2[0, int(v), int(u)], 0, (phi, k))
            self.assertLess(metric.angle_diff(angle_of(m2, int(u), int(v)), moved), 1e-5, (phi, k))

    def test_a_turned_relabelling_is_matched_back_and_scored_view_by_view(self):
        a, b = labelled_twice()
        repeatability.check_pair(a, b)
        pairs, unpaired = repeatability.pair_views(a, b)
        self.assertEqual((len(pairs), unpaired), (6, 0))
        result = repeatability.compare(a, b, pairs)
        self.assertEqual(result["turned"], 6)
        self.assertEqual(result["misaligned"], 0)
        self.assertEqual(result["both"], 6)
        # Every view but the last: A's best positive is B's, turned back.
        self.assertAlmostEqual(result["oracle_accuracy"], 5 / 6)
        self.assertAlmostEqual(result["any_positive_accuracy"], 5 / 6)
        self.assertEqual(result["oracle_per_scenario"], {"?": {"accuracy": 5 / 6, "views": 6}})
        # Against itself (no turn), the oracle is exact.
        same = repeatability.compare(a, a, pairs)
        self.assertEqual((same["turned"], same["oracle_accuracy"]), (0, 1.0))

    def test_runs_that_are_not_the_same_scenes_labelled_twice_are_refused(self):
        a, b = labelled_twice()
        with self.assertRaisesRegex(ValueError, "same label_salt and neighbours"):
            repeatability.check_pair(a, a)
        a.manifest["generator"]["neighbours"] = False  # alone vs with neighbours: allowed
        b.manifest["generator"]["label_salt"] = 0
        repeatability.check_pair(a, b)
        b.manifest["generator"]["first_seed"] = 2
        with self.assertRaisesRegex(ValueError, "first_seed"):
            repeatability.check_pair(a, b)

    def test_duplicate_detections_are_not_paired(self):
        a, b = labelled_twice()
        b.meta[1] = dict(b.meta[0])  # two B views claim instance 0:0
        pairs, unpaired = repeatability.pair_views(a, b)
        self.assertEqual(len(pairs), 4)
        self.assertNotIn(0, [p[0] for p in pairs])
        self.assertEqual(unpaired, 2)


if __name__ == "__main__":
    unittest.main()


def write_attempts(root, rows, l=8, contract=None, stem="attempts_pile_5", fmt="mvgrasp-attempt-views-2",
                   alternatives=None):
    """A `sim eval --attempt-views` folder: one episode whose views are
    filled with the row's index so each row can be told apart;
    `alternatives` gives each row's `alternative` (format 2)."""
    os.makedirs(root, exist_ok=True)
    views = np.stack([np.full((l, l), float(k), np.float32) for k in range(len(rows))]) if rows else \
        np.zeros((0, l, l), np.float32)
    np.save(os.path.join(root, f"{stem}.npy"), views)
    with open(os.path.join(root, f"{stem}.json"), "w") as f:
        records = [{"step": k, "view": "top", "pixel": list(p), "quality": 0.5, "outcome": o}
                   for k, (p, o) in enumerate(rows)]
        if alternatives is not None:
            for r, alt in zip(records, alternatives):
                r["alternative"] = alt
        json.dump(records, f)
    with open(os.path.join(root, "manifest.json"), "w") as f:
        json.dump({"format": fmt,
                   "contract": contract or {"input_size_px": l, "pixel_size_m": 0.0033333, "normalisation": "cube-v1"}},
                  f)


class PhysicsAttempts(unittest.TestCase):
    ROWS = [((1, 2), "ok"), ((3, 4), "slip during lift"), ((5, 6), "collision on approach: the table (palm)"),
            ((0, 7), "width too small"), ((7, 0), "object missed"),
            ((2, 2), "collision on approach: the object (left pad), at the grasp")]

    def test_held_and_the_network_s_failures_are_read_the_rest_left_out(self):
        with tempfile.TemporaryDirectory() as d:
            write_attempts(d, self.ROWS)
            a = physics.load(d)
            self.assertEqual(len(a), 4)
            np.testing.assert_array_equal(a.held, [1.0, 0.0, 0.0, 0.0])
            np.testing.assert_array_equal(a.pixels, [[1, 2], [3, 4], [0, 7], [2, 2]])
            # Each row keeps its own view (row k is filled with k).
            np.testing.assert_array_equal(a.views[:, 0, 0], [0.0, 1.0, 3.0, 5.0])
            self.assertIn("4 attempts (0 of them alternatives), 25.0% held", physics.summary(a))
            self.assertIn("collision on approach: the object 1", physics.summary(a))
            slips_only = physics.load(d, failures=("slip during lift",))
            np.testing.assert_array_equal(slips_only.held, [1.0, 0.0])
            self.assertEqual(physics.check_contract(a, {"input_size_px": 8, "pixel_size_m": 0.0033333333,
                                                        "normalisation": "cube-v1"}), [])
            wrong = physics.check_contract(a, {"input_size_px": 72, "pixel_size_m": 0.0033333333,
                                               "normalisation": "cube-v1"})
            self.assertEqual(len(wrong), 1)
            self.assertIn("input_size_px", wrong[0])

    def test_bad_folders_say_why(self):
        with tempfile.TemporaryDirectory() as d:
            with self.assertRaisesRegex(ValueError, "no manifest.json"):
                physics.load(d)
            with self.assertRaisesRegex(ValueError, "no --attempt-views folder"):
                physics.load("")
            write_attempts(os.path.join(d, "a"), [((9, 0), "ok")])
            with self.assertRaisesRegex(ValueError, "outside the 8 px view"):
                physics.load(os.path.join(d, "a"))
            write_attempts(os.path.join(d, "b"), self.ROWS)
            os.remove(os.path.join(d, "b", "attempts_pile_5.json"))
            with open(os.path.join(d, "b", "attempts_pile_5.json"), "w") as f:
                json.dump([{"pixel": [0, 0], "outcome": "ok"}], f)
            with self.assertRaisesRegex(ValueError, "views \\(6, 8, 8\\) for 1 rows"):
                physics.load(os.path.join(d, "b"))
            write_attempts(os.path.join(d, "c"), self.ROWS)
            write_attempts(os.path.join(d, "e"), self.ROWS, l=8,
                           contract={"input_size_px": 8, "pixel_size_m": 0.005, "normalisation": "cube-v1"})
            with self.assertRaisesRegex(ValueError, "contract"):
                physics.load(f"{d}/c,{d}/e")
            two = physics.load(f"{d}/c,{d}/c")
            self.assertEqual(len(two), 8)
            write_attempts(os.path.join(d, "f"), self.ROWS, fmt="mvgrasp-attempt-views-9")
            with self.assertRaisesRegex(ValueError, "format 'mvgrasp-attempt-views-9'"):
                physics.load(os.path.join(d, "f"))

    def test_alternatives_are_read_unless_left_out_and_format_1_still_reads(self):
        with tempfile.TemporaryDirectory() as d:
            # Rows 1 and 3 are grasps ranked below the tried ones.
            write_attempts(d, self.ROWS, alternatives=[False, True, False, True, False, False])
            every = physics.load(d)
            self.assertEqual(len(every), 4)
            self.assertIn("4 attempts (2 of them alternatives)", physics.summary(every))
            own = physics.load(d, alternatives=False)
            np.testing.assert_array_equal(own.views[:, 0, 0], [0.0, 5.0])
            np.testing.assert_array_equal(own.held, [1.0, 0.0])
            write_attempts(os.path.join(d, "old"), self.ROWS, fmt="mvgrasp-attempt-views-1")
            self.assertEqual(len(physics.load(os.path.join(d, "old"), alternatives=False)), 4)

    def test_symmetries_move_the_pixel_with_the_view(self):
        rng = np.random.default_rng(2)
        views = rng.uniform(0, 1, (4, 9, 9)).astype(np.float32)
        pixels = rng.integers(0, 9, (4, 2))
        seen = set()
        for k in range(8):
            v, p = physics.symmetry(views, pixels, k)
            for n in range(4):
                # The value under the pixel travels with it.
                self.assertEqual(v[n, p[n, 1], p[n, 0]], views[n, pixels[n, 1], pixels[n, 0]])
            seen.add(v.tobytes())
        self.assertEqual(len(seen), 8, "eight different images")
        np.testing.assert_array_equal(physics.symmetry(views, pixels, 0)[0], views)

    def test_the_kernel_is_the_planner_s(self):
        k = physics.gaussian_kernel(1.0)
        self.assertEqual(len(k), 7)  # radius ceil(3 sigma), as core::decode::smooth
        self.assertAlmostEqual(float(k.sum()), 1.0, places=6)
        self.assertEqual(int(np.argmax(k)), 3)
        np.testing.assert_allclose(k, k[::-1])
        np.testing.assert_array_equal(physics.gaussian_kernel(0.0), [1.0])  # smoothing off, as in core


class AttemptViews(unittest.TestCase):
    """The views of attempt folders as a label-free dataset to distil on."""

    CONTRACT = {"input_size_px": 8, "pixel_size_m": 0.0025, "normalisation": "cube-v1"}

    def test_every_row_becomes_a_view_that_trains_beside_the_dataset_it_is_like(self):
        with tempfile.TemporaryDirectory() as d:
            like, a, b, out = (os.path.join(d, n) for n in ("like", "a", "b", "out"))
            write_dataset(like)
            write_attempts(a, PhysicsAttempts.ROWS, contract=self.CONTRACT)
            write_attempts(b, PhysicsAttempts.ROWS[:2], contract=self.CONTRACT, stem="attempts_isolated_2")
            attempt_views.main(["--like", like, "--out", out, a, b])
            ds = dataset.load(out)
            self.assertEqual(dataset.check(ds), [])
            # Every row, whatever its outcome, in folder then file order (row k's view is filled with k).
            np.testing.assert_array_equal(ds.views[:, 0, 0, 0], [0, 1, 2, 3, 4, 5, 0, 1])
            self.assertEqual((float(np.abs(ds.maps).max()), len(ds.grasps)), (0.0, 0))
            self.assertEqual({m["instance"] for m in ds.meta}, {"a:attempts_pile_5", "b:attempts_isolated_2"})
            both = dataset.load(f"{like},{out}")
            self.assertEqual(len(both.meta), 3 + 8)

    def test_a_folder_the_network_could_not_read_is_refused(self):
        with tempfile.TemporaryDirectory() as d:
            like, a = os.path.join(d, "like"), os.path.join(d, "a")
            write_dataset(like)
            write_attempts(a, PhysicsAttempts.ROWS, contract={**self.CONTRACT, "pixel_size_m": 0.005})
            with self.assertRaisesRegex(SystemExit, "pixel_size_m"):
                attempt_views.main(["--like", like, "--out", os.path.join(d, "out"), a])
            with self.assertRaisesRegex(SystemExit, "no manifest.json"):
                attempt_views.main(["--like", like, "--out", os.path.join(d, "out"), d])


class PhysicsScore(unittest.TestCase):
    def test_auc_counts_pairs_held_above_failed_ties_half(self):
        self.assertEqual(physics_score.auc([0.1, 0.4, 0.35, 0.8], [0, 0, 1, 1]), 0.75)
        self.assertEqual(physics_score.auc([0.5, 0.5], [1, 0]), 0.5)
        self.assertEqual(physics_score.auc([0.9, 0.2], [1, 0]), 1.0)
        self.assertTrue(np.isnan(physics_score.auc([0.3, 0.4], [1, 1])))
        rng = np.random.default_rng(5)
        scores = rng.integers(0, 6, 200) / 5.0  # many ties
        held = (rng.uniform(size=200) < 0.3 + 0.5 * scores).astype(np.float32)
        pairs = [(1.0 if h > f else 0.5 if h == f else 0.0)
                 for h in scores[held > 0.5] for f in scores[held < 0.5]]
        self.assertAlmostEqual(physics_score.auc(scores, held), float(np.mean(pairs)), places=12)

    def test_brier_and_calibration_bins(self):
        scores, held = [0.1, 0.3, 0.85, 0.95, 1.0], [0, 1, 1, 1, 0]
        self.assertAlmostEqual(physics_score.brier(scores, held), (0.01 + 0.49 + 0.0225 + 0.0025 + 1.0) / 5)
        bins = physics_score.calibration(scores, held, edges=(0.0, 0.5, 0.9, 1.0))
        self.assertEqual([b["attempts"] for b in bins], [2, 1, 2])  # 1.0 falls in the last, closed bin
        self.assertAlmostEqual(bins[0]["mean_quality"], 0.2)
        self.assertEqual([b["held"] for b in bins], [0.5, 1.0, 0.5])
        empty = physics_score.calibration(scores, held, edges=(0.0, 0.05, 1.0))[0]
        self.assertEqual(empty["attempts"], 0)
        self.assertTrue(np.isnan(empty["held"]))

    def test_the_model_contract_is_read_from_metadata(self):
        meta = {"mvgrasp.input_size_px": "72", "mvgrasp.pixel_size_m": "0.003333333",
                "mvgrasp.normalisation": "cube-v1", "mvgrasp.outputs": "cos2phi,quality,sin2phi,width"}
        contract, channel = physics_score.model_contract(meta)
        self.assertEqual(contract, {"input_size_px": 72, "pixel_size_m": 0.003333333, "normalisation": "cube-v1"})
        self.assertEqual(channel, 1)
        with self.assertRaisesRegex(ValueError, "no quality"):
            physics_score.model_contract({**meta, "mvgrasp.outputs": "cos2phi,sin2phi,width"})
        with self.assertRaisesRegex(ValueError, "mvgrasp.normalisation"):
            physics_score.model_contract({k: v for k, v in meta.items() if k != "mvgrasp.normalisation"})
