"""scripts/compare_eval.py: totals over settings, differences, label table."""

import json
import os
import sys
import tempfile
import unittest

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))
import compare_eval  # noqa: E402

FAILURES = ("collision on approach", "object missed", "slip during lift", "width too small")


def summary(scenario, setting, removed, objects, attempts, slips=0, collisions=0):
    failures = dict.fromkeys(FAILURES, 0)
    failures["slip during lift"] = slips
    failures["collision on approach"] = collisions
    return {"scenario": scenario, "setting": setting, "removed": removed, "objects": objects,
            "attempts": attempts, "failures": failures}


def run(seed, summaries, attempts):
    return {"command": ["sim", "eval", "--seed", str(seed)], "summaries": summaries,
            "episodes": [{"scenario": "pile", "attempts": attempts}]}


A = run(800000, [summary("pile", "all:0.1", 5, 8, 7, slips=1, collisions=1),
                 summary("pile", "top-down:0.1", 6, 8, 6),
                 summary("clutter", "all:0.1", 30, 32, 33, slips=3)],
        [["ok", 0.7, 90.0, 90.0, 3.0, "positive", "box"],
         ["slip during lift", 0.5, 120.0, 90.0, 3.0, "not antipodal", "mug"],
         ["collision on approach: a neighbour (palm), at the grasp", 0.6, 100.0, 90.0, 3.0, None, None],
         ["object missed", 0.6, 100.0, 90.0, 3.0, None, None],
         # the trial ran and the pads closed on nothing: lifted, labelled, failed
         ["object missed", 0.6, 100.0, 90.0, 3.0, "positive", "box"],
         ["ok", 0.6, 80.0, 90.0, 3.0, "not antipodal", "box"]])
B = run(800000, [summary("pile", "all:0.1", 4, 8, 8, slips=2, collisions=2),
                 summary("clutter", "all:0.1", 31, 32, 32, slips=1)], [])


class CompareEval(unittest.TestCase):
    def test_totals_sum_settings_and_scenarios(self):
        t = compare_eval.totals(A)
        self.assertEqual((t["pile"]["removed"], t["pile"]["objects"], t["pile"]["attempts"]), (11, 16, 13))
        self.assertEqual(t["pile"]["slip during lift"], 1)
        self.assertEqual((t["all"]["removed"], t["all"]["attempts"], t["all"]["slip during lift"]), (41, 46, 4))

    def test_held_by_label_counts_every_trial_and_only_trials(self):
        self.assertEqual(compare_eval.held_by_label(A), {"positive": (1, 2), "not antipodal": (1, 2)})

    def test_first_attempts_are_each_episode_s_first(self):
        two = dict(A, episodes=A["episodes"] + [{"scenario": "pile", "attempts": []},
                                                 {"scenario": "clutter", "attempts": [A["episodes"][0]["attempts"][1]]}])
        # Episodes: A's (first attempt held, positive); one with no attempt; one whose first slipped.
        self.assertEqual(compare_eval.first_attempts(two), (2, 1, 1))
        self.assertEqual(compare_eval.first_attempts(B), (0, 0, 0))

    def test_report_shows_differences_to_the_first_run(self):
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for name, r in (("a", A), ("b", B)):
                os.mkdir(os.path.join(tmp, name))
                with open(os.path.join(tmp, name, "eval.json"), "w") as f:
                    json.dump(r, f)
                paths.append(os.path.join(tmp, name))
            text = compare_eval.report(paths)
        self.assertIn("seeds: 800000\n", text)
        sections = dict(part.split("\n", 1) for part in text.split("\n\n")[1:])
        pile_b = sections["pile"].splitlines()[1]
        self.assertIn("removed     4 of     8", pile_b)
        self.assertIn("(removed -7)", pile_b)  # pile: 4 against 11
        self.assertIn("(removed -6)", sections["all"])  # all: 35 against 41
        self.assertIn("not antipodal 1/2 (0.500)", text)
        self.assertIn("labelled positive 2/4 (0.500)", text)
        self.assertIn("a                        1 episodes: labelled positive 1 (1.000), held 1 (1.000)", text)
        self.assertNotIn("b                        0 episodes", text)  # B has no episodes: no line

    def test_slips_by_pose_count_trials_with_a_tilt_only(self):
        tail = ["top", [36, 36], 5.0, 0.02, ["deepened"]]
        c = run(800000, [summary("pile", "all:0.1", 1, 4, 5)],
                [["slip during lift", 0.7, 90.0, 90.0, 3.0, "positive", "t_shape"] + tail + [91.0],
                 ["ok", 0.7, 90.0, 90.0, 3.0, "positive", "t_shape"] + tail + [29.9],
                 ["slip during lift", 0.7, 90.0, 90.0, 3.0, "not antipodal", "t_shape"] + tail + [30.0],
                 ["ok", 0.7, 90.0, 90.0, 3.0, "positive", "mug"] + tail + [170.0],
                 # matched an object, never reached the trial: not counted
                 ["collision on approach: the table (palm), at the grasp", 0.6, 100.0, 90.0, 3.0, None, None]
                 + tail[:3] + [None, [], 10.0]])
        self.assertEqual(compare_eval.slips_by_pose(c), {("t_shape", "toppled"): (2, 2),
                                                         ("t_shape", "upright"): (0, 1),
                                                         ("mug", "upside down"): (0, 1)})
        # Runs before the tilt was recorded: nothing, and no section.
        self.assertEqual(compare_eval.slips_by_pose(A), {})
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for name, r in (("a", A), ("c", c)):
                with open(os.path.join(tmp, name + ".json"), "w") as f:
                    json.dump(r, f)
                paths.append(os.path.join(tmp, name + ".json"))
            text = compare_eval.report(paths)
            self.assertNotIn("by family and pose", compare_eval.report(paths[:1]))
        self.assertIn("a.json                   (no tilt recorded)", text)
        self.assertIn("c.json                   mug upside down 0/1, t_shape toppled 2/2, t_shape upright 0/1", text)

    def test_different_seeds_are_flagged(self):
        other = dict(B, command=["sim", "eval", "--seed", "700000"])
        with tempfile.TemporaryDirectory() as tmp:
            for name, r in (("a.json", A), ("b.json", other)):
                with open(os.path.join(tmp, name), "w") as f:
                    json.dump(r, f)
            text = compare_eval.report([os.path.join(tmp, "a.json"), os.path.join(tmp, "b.json")])
        self.assertIn("not comparable", text)


class Judged(unittest.TestCase):
    RUN = {"command": ["sim", "eval", "--seed", "1"], "summaries": [], "episodes": [],
           "judged_models": ["a.onnx", "b.onnx"],
           "judged_frames": [{"scenario": "pile", "seed": 1, "step": s, "outcomes": o} for s, o in enumerate([
               ["held", "held"], ["held", "slip during lift"], ["held", "no grasp"], ["held", "held"],
               ["collision on approach", "held"]])]}

    def test_pairs_count_each_state_against_the_first_model(self):
        rows = compare_eval.judged_pairs(self.RUN)
        self.assertEqual([r[:5] for r in rows], [("a.onnx", 4, 5, 0, 0), ("b.onnx", 3, 5, 1, 2)])
        self.assertEqual(rows[0][5], 1.0)
        self.assertIn("b.onnx", compare_eval.report_runs([self.RUN], ["r"]))
        self.assertEqual(compare_eval.judged_pairs({"summaries": []}), [])

    def test_the_sign_test_is_exact_and_two_sided(self):
        self.assertEqual(compare_eval.sign_test(0, 0), 1.0)
        self.assertAlmostEqual(compare_eval.sign_test(1, 2), 1.0)
        self.assertAlmostEqual(compare_eval.sign_test(0, 5), 2 / 32)
        self.assertAlmostEqual(compare_eval.sign_test(8, 2), 2 * 56 / 1024)
        self.assertEqual(compare_eval.sign_test(8, 2), compare_eval.sign_test(2, 8))


def episode(scenario, seed, setting, removed, objects):
    return {"scenario": scenario, "seed": seed, "setting": setting, "removed": removed, "objects": objects,
            "attempts": []}


class Paired(unittest.TestCase):
    # Run A and run B on the same four scenes under one setting; B also ran a
    # second setting that A did not (left out of the pairs).
    A = {"command": ["sim", "eval", "--seed", "5"], "summaries": [],
         "episodes": [episode("pile", 5, "all:0.1", 3, 5), episode("pile", 6, "all:0.1", 5, 5),
                      episode("clutter", 5, "all:0.1", 10, 12), episode("clutter", 6, "all:0.1", 12, 12)]}
    B = {"command": ["sim", "eval", "--seed", "5"], "summaries": [],
         "episodes": [episode("pile", 5, "all:0.1", 5, 5), episode("pile", 6, "all:0.1", 5, 5),
                      episode("clutter", 5, "all:0.1", 11, 12), episode("clutter", 6, "all:0.1", 11, 12),
                      episode("clutter", 6, "top-down:0.1", 12, 12)]}

    def test_episodes_pair_by_scenario_seed_and_setting(self):
        pairs = compare_eval.paired_episodes(self.A, self.B)
        self.assertEqual(pairs, {("clutter", 5, "all:0.1"): (10, 11, 12), ("clutter", 6, "all:0.1"): (12, 11, 12),
                                 ("pile", 5, "all:0.1"): (3, 5, 5), ("pile", 6, "all:0.1"): (5, 5, 5)})

    def test_different_scenes_are_refused(self):
        other = dict(self.B, episodes=[episode("pile", 5, "all:0.1", 4, 6)])
        with self.assertRaisesRegex(ValueError, "not the same scene"):
            compare_eval.paired_episodes(self.A, other)

    def test_summary_counts_episodes_and_brackets_the_total(self):
        n, total, lo, hi, better, worse, p = compare_eval.paired_summary([2, 0, 1, -1])
        self.assertEqual((n, total, better, worse), (4, 2, 2, 1))
        self.assertAlmostEqual(p, compare_eval.sign_test(2, 1))
        # Every resample's total lies between 4 x min and 4 x max.
        self.assertTrue(-4 <= lo <= total <= hi <= 8, (lo, hi))
        # All episodes equal: no spread, no evidence.
        self.assertEqual(compare_eval.paired_summary([1, 1, 1]), (3, 3, 3, 3, 3, 0, 0.25))
        # The same call gives the same interval (fixed generator seed).
        self.assertEqual(compare_eval.paired_summary([2, 0, 1, -1]), (n, total, lo, hi, better, worse, p))
        self.assertEqual(compare_eval.paired_summary([]), (0, 0, 0, 0, 0, 0, 1.0))

    def test_report_and_pooled_report(self):
        with tempfile.TemporaryDirectory() as tmp:
            paths = []
            for name, r in (("a", self.A), ("b", self.B)):
                with open(os.path.join(tmp, name + ".json"), "w") as f:
                    json.dump(r, f)
                paths.append(os.path.join(tmp, name + ".json"))
            text = compare_eval.report(paths)
            pooled = compare_eval.report_paired([paths, paths])
            self.assertEqual(compare_eval.main(["--paired", paths[0]]), 2)
            self.assertEqual(compare_eval.main(["--paired", paths[0] + ":" + os.path.join(tmp, "none.json")]), 1)
        self.assertIn("paired episodes, b.json against a.json", text)
        self.assertIn("pile          2 episodes,    10 objects: removed 8 (0.800) against 10 (1.000), +2", text)
        self.assertIn("clutter       2 episodes,    24 objects: removed 22 (0.917) against 22 (0.917), +0", text)
        self.assertIn("episodes better 1 / worse 1", text)
        # Pooled: the same pair twice is eight episodes, twice the difference.
        all_line = pooled.split("pooled over 2 pairs of runs\n")[1].splitlines()[-1]
        self.assertIn("all           8 episodes,    68 objects: removed 60 (0.882) against 64 (0.941), +4", all_line)


if __name__ == "__main__":
    unittest.main()
