"""Tests that need PyTorch, onnx and onnxruntime; skipped, saying so, without them.

CI does not install PyTorch (a 5 GB CUDA build); run these where it is:
    python3 -m unittest discover -s training/tests -v
"""

import importlib.util
import os
import sys
import tempfile
import unittest

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))

MISSING = [m for m in ("torch", "onnx", "onnxruntime") if importlib.util.find_spec(m) is None]
REASON = f"needs {', '.join(MISSING)} (not installed; CI does not install PyTorch)"


@unittest.skipIf(MISSING, REASON)
class BatchAugmentation(unittest.TestCase):
    """augment_torch.py must do what augment.py does, to the bit, for the same draws."""

    def batch(self, n=8, l=24, seed=0):
        rng = np.random.default_rng(seed)
        views = np.where(rng.random((n, 1, l, l)) < 0.5, rng.uniform(0.2, 0.9, (n, 1, l, l)), 0).astype(np.float32)
        maps = rng.normal(size=(n, 4, l, l)).astype(np.float32)
        return views, maps

    def test_symmetries_and_rescale_equal_the_numpy_ones(self):
        import torch
        from mvgrasp_train import augment, augment_torch
        views, maps = self.batch()
        k = np.arange(8)
        factors = np.array([0.95, 1.05, 1.0, 0.97, 1.03, 0.951, 1.049, 1.011])
        got_v, got_m = augment_torch.symmetry(torch.from_numpy(views), torch.from_numpy(maps), torch.from_numpy(k))
        got_v, got_m = augment_torch.rescale(got_v, got_m, torch.from_numpy(factors))
        for i in range(8):
            want_v, want_m = augment.symmetry(views[i], maps[i], int(k[i]))
            want_v, want_m = augment.rescale(want_v, want_m, float(factors[i]))
            np.testing.assert_array_equal(got_v[i].numpy(), want_v)
            np.testing.assert_array_equal(got_m[i].numpy(), want_m)

    def test_corruption_touches_only_the_surface_and_stays_in_range(self):
        import torch
        from mvgrasp_train import augment_torch
        views, maps = self.batch(n=64)
        generator = torch.Generator().manual_seed(1)
        out = augment_torch.corrupt(torch.from_numpy(views), generator).numpy()
        surface = views > 0
        self.assertTrue(np.all(out[~surface] == 0))
        self.assertTrue(np.all((out >= 0) & (out <= 1)))
        moved = np.abs(out - views)[surface & (out > 0)]
        self.assertGreater(moved.mean(), 0.003)  # the 1 cm noise is there
        dropped = np.mean(out[surface] == 0)
        self.assertGreater(dropped, 0.005)  # about 2% dropout
        self.assertLess(dropped, 0.05)

    def test_augment_keeps_views_and_targets_paired(self):
        import torch
        from mvgrasp_train import augment_torch
        views, maps = self.batch(n=32)
        maps[:, 0] = (views[:, 0] > 0) * 0.7  # quality painted exactly on the surface
        generator = torch.Generator().manual_seed(2)
        v, m = augment_torch.augment(torch.from_numpy(views), torch.from_numpy(maps), generator)
        # Dropout may empty a surface pixel of the view, never the reverse.
        self.assertTrue(bool(((v[:, 0] > 0) <= (m[:, 0] > 0)).all()))
        self.assertTrue(bool((m[:, 0] > 0).any()))


    def test_a_mask_of_one_keeps_each_view_s_bottom_row_below(self):
        import torch
        from mvgrasp_train import augment, augment_torch
        views = np.zeros((64, 1, 24, 24), np.float32)
        views[:, 0, -1, :] = 0.5  # a table edge along the bottom
        maps = np.zeros((64, 4, 24, 24), np.float32)
        maps[:, 0] = views[:, 0] > 0
        mask = np.where(np.arange(64) % 2 == 0, augment.KEEP_DOWN, augment.ALL_SYMMETRIES)
        generator = torch.Generator().manual_seed(3)
        _, m = augment_torch.augment(torch.from_numpy(views), torch.from_numpy(maps), generator, scale=0,
                                     mask=torch.from_numpy(mask))
        bottom = (m[:, 0, -1, :] > 0).all(dim=1).numpy()
        self.assertTrue(bottom[0::2].all(), "front and side views keep the table below")
        self.assertFalse(bottom[1::2].all(), "top views turn")


@unittest.skipIf(MISSING, REASON)
class Network(unittest.TestCase):
    def setUp(self):
        import torch
        torch.manual_seed(0)

    def trained_a_little(self, architecture, size=48):
        import torch
        from mvgrasp_train.model import GraspNet
        model = GraspNet(architecture)
        opt = torch.optim.Adam(model.parameters(), 1e-3)
        x = torch.rand(4, 1, size, size)
        for _ in range(3):  # moves the BatchNorm statistics away from their defaults
            opt.zero_grad()
            model(x).square().mean().backward()
            opt.step()
        return model.eval()

    def test_output_is_the_input_size_with_quality_in_0_1(self):
        import torch
        from mvgrasp_train.model import GraspNet
        for arch in ("paper", "narrow", "skip", "wide", "lite"):
            for size in (72, 96):
                out = GraspNet(arch).eval()(torch.rand(3, 1, size, size))
                self.assertEqual(tuple(out.shape), (3, 4, size, size))
                self.assertTrue(bool(((out[:, 0] >= 0) & (out[:, 0] <= 1)).all()))

    def test_the_paper_layers_are_there(self):
        from torch import nn
        from mvgrasp_train.model import GraspNet
        convs = [m for m in GraspNet("paper").body.modules() if isinstance(m, (nn.Conv2d, nn.ConvTranspose2d))]
        shapes = [(type(m).__name__[:4], m.kernel_size[0], m.out_channels, m.stride[0]) for m in convs]
        self.assertEqual(shapes, [("Conv", 9, 8, 3), ("Conv", 5, 16, 2), ("Conv", 5, 16, 2), ("Conv", 3, 32, 1),
                                  ("Conv", 3, 32, 1), ("Conv", 3, 32, 1), ("Conv", 3, 32, 1), ("Conv", 3, 32, 1),
                                  ("Conv", 3, 32, 1), ("Conv", 5, 16, 2), ("Conv", 5, 32, 2), ("Conv", 9, 32, 3)])
        bns = [m for m in GraspNet("paper").body.modules() if isinstance(m, nn.BatchNorm2d)]
        self.assertEqual(len(bns), 12)

    def test_folding_batchnorm_keeps_the_function(self):
        import torch
        from mvgrasp_train.model import fold_batchnorm
        model = self.trained_a_little("paper")
        x = torch.rand(2, 1, 48, 48)
        with torch.no_grad():
            diff = (model(x) - fold_batchnorm(model)(x)).abs().max().item()
        self.assertLess(diff, 1e-5)

    def test_the_sub_pixel_form_keeps_the_function(self):
        import torch
        from torch import nn
        from mvgrasp_train.model import fold_batchnorm, subpixel
        for arch in ("paper", "narrow", "skip", "wide"):
            folded = fold_batchnorm(self.trained_a_little(arch))
            fast = subpixel(folded)
            self.assertFalse(any(isinstance(m, nn.ConvTranspose2d) for m in fast.modules()))
            self.assertEqual(sum(isinstance(m, nn.PixelShuffle) for m in fast.modules()), 6)
            for size in (48, 72):
                x = torch.rand(2, 1, size, size)
                with torch.no_grad():
                    diff = (folded(x) - fast(x)).abs().max().item()
                self.assertLess(diff, 1e-5, f"{arch} at {size} px")

    def test_a_skip_network_starts_as_the_narrow_run_it_extends_and_exports(self):
        import torch
        from mvgrasp_train import export
        from mvgrasp_train.model import GraspNet
        from mvgrasp_train.train import start_from
        narrow = self.trained_a_little("narrow")
        skip = GraspNet("skip")
        start_from(skip, {"architecture": "narrow", "state_dict": narrow.state_dict()}, "narrow run")
        skip.eval()
        self.assertEqual(len(skip.skips), 2)
        self.assertTrue(all(bool((c.weight == 0).all()) for c in skip.skips))
        x = torch.rand(2, 1, 48, 48)
        with torch.no_grad():
            self.assertEqual((skip(x) - narrow(x)).abs().max().item(), 0.0)
        with self.assertRaises(SystemExit):  # only narrow extends to skip
            start_from(GraspNet("skip"), {"architecture": "paper", "state_dict": {}}, "paper run")
        # Trained a little, the skips carry weight and the export still matches.
        skip = self.trained_a_little("skip")
        self.assertTrue(any(bool((c.weight != 0).any()) for c in skip.skips))
        contract = {"input_size_px": 48, "pixel_size_m": 0.0025, "width_scale_m": 0.2, "normalisation": "cube-v1"}
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "m.onnx")
            ops = export.export(skip, 48, path, export.contract_metadata(contract, "t-1", "sim-test"))
            self.assertIn("Add", ops)
            views = np.random.default_rng(5).random((3, 1, 48, 48), dtype=np.float32)
            self.assertLess(export.compare(skip, path, views)[0], export.TOLERANCE)

    def test_a_lite_network_starts_from_the_narrow_run_and_exports_its_last_layer_as_it_is(self):
        import onnx
        import torch
        from torch import nn
        from mvgrasp_train import export
        from mvgrasp_train.model import GraspNet, fold_batchnorm, start_lite, subpixel
        from mvgrasp_train.train import start_from
        narrow = self.trained_a_little("narrow")
        lite = GraspNet("lite")
        start_from(lite, {"architecture": "narrow", "state_dict": narrow.state_dict()}, "narrow run")
        big, small = narrow.body[-1][0].weight, lite.body[-1][0].weight
        self.assertEqual(tuple(small.shape), (32, 8, 3, 3))
        self.assertTrue(torch.equal(small, big[:, :, 3:6, 3:6]))  # each phase's centre tap
        self.assertTrue(torch.equal(lite.heads.weight, narrow.heads.weight))
        with self.assertRaises(ValueError):
            start_lite(GraspNet("narrow"), narrow.state_dict())
        # Trained a little: the sub-pixel form keeps the function and the last layer.
        lite = self.trained_a_little("lite")
        folded = fold_batchnorm(lite)
        fast = subpixel(folded)
        self.assertEqual(sum(isinstance(m, nn.PixelShuffle) for m in fast.modules()), 5)
        self.assertEqual(sum(isinstance(m, nn.ConvTranspose2d) for m in fast.modules()), 1)
        x = torch.rand(2, 1, 48, 48)
        with torch.no_grad():
            self.assertLess((folded(x) - fast(x)).abs().max().item(), 1e-5)
        contract = {"input_size_px": 48, "pixel_size_m": 0.0025, "width_scale_m": 0.2, "normalisation": "cube-v1"}
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "m.onnx")
            ops = export.export(lite, 48, path, export.contract_metadata(contract, "t-1", "sim-test"))
            self.assertIn("ConvTranspose", ops)
            kept = [n for n in onnx.load(path).graph.node if n.op_type == "ConvTranspose"]
            self.assertEqual([list(a.ints) for a in kept[0].attribute if a.name == "kernel_shape"], [[3, 3]])
            views = np.random.default_rng(5).random((3, 1, 48, 48), dtype=np.float32)
            self.assertLess(export.compare(lite, path, views)[0], export.TOLERANCE)

    def test_a_wide_network_starts_as_the_narrow_run_it_widens_and_then_learns_with_its_new_channels(self):
        import torch
        from mvgrasp_train import export
        from mvgrasp_train.model import GraspNet, widen
        from mvgrasp_train.train import start_from
        narrow = self.trained_a_little("narrow")
        wide = GraspNet("wide")
        start_from(wide, {"architecture": "narrow", "state_dict": narrow.state_dict()}, "narrow run")
        wide.eval()
        self.assertEqual(wide.heads.in_channels, 2 * narrow.heads.in_channels)
        self.assertGreater(sum(p.numel() for p in wide.parameters()),
                           3.5 * sum(p.numel() for p in narrow.parameters()))
        x = torch.rand(2, 1, 48, 48)
        with torch.no_grad():
            self.assertLess((wide(x) - narrow(x)).abs().max().item(), 1e-6)
        with self.assertRaises(SystemExit):  # only narrow widens
            start_from(GraspNet("wide"), {"architecture": "paper", "state_dict": {}}, "paper run")
        with self.assertRaises(ValueError):
            widen(GraspNet("narrow"), narrow.state_dict())
        # One step moves the zero weights from new channels to the heads.
        new_to_heads = wide.heads.weight[:, narrow.heads.in_channels:]
        self.assertEqual(new_to_heads.abs().max().item(), 0.0)
        opt = torch.optim.Adam(wide.parameters(), 1e-3)
        wide.train()
        opt.zero_grad()
        (wide(x) - 0.5).square().mean().backward()
        opt.step()
        self.assertGreater(wide.heads.weight[:, narrow.heads.in_channels:].abs().max().item(), 0.0)
        wide.eval()
        contract = {"input_size_px": 48, "pixel_size_m": 0.0025, "width_scale_m": 0.2, "normalisation": "cube-v1"}
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "m.onnx")
            export.export(wide, 48, path, export.contract_metadata(contract, "t-1", "sim-test"))
            views = np.random.default_rng(6).random((3, 1, 48, 48), dtype=np.float32)
            self.assertLess(export.compare(wide, path, views)[0], export.TOLERANCE)

    def test_export_matches_pytorch_and_carries_the_contract(self):
        import onnx
        import onnxruntime
        from mvgrasp_train import export
        model = self.trained_a_little("narrow", 48)
        contract = {"input_size_px": 48, "pixel_size_m": 0.0025, "width_scale_m": 0.2, "normalisation": "cube-v1"}
        with tempfile.TemporaryDirectory() as d:
            path = os.path.join(d, "m.onnx")
            ops = export.export(model, 48, path, export.contract_metadata(contract, "t-1", "sim-test"))
            self.assertNotIn("BatchNormalization", ops)
            self.assertNotIn("ConvTranspose", ops)
            self.assertIn("DepthToSpace", ops)
            meta = {p.key: p.value for p in onnx.load(path).metadata_props}
            self.assertEqual(meta["mvgrasp.input_size_px"], "48")
            self.assertEqual(meta["mvgrasp.outputs"], "quality,cos2phi,sin2phi,width")
            self.assertEqual(meta["mvgrasp.data_version"], "sim-test")
            for batch in (1, 5):  # the batch axis is dynamic
                views = np.random.default_rng(batch).random((batch, 1, 48, 48), dtype=np.float32)
                worst, _ = export.compare(model, path, views)
                self.assertLess(worst, export.TOLERANCE)
            session = onnxruntime.InferenceSession(path, providers=["CPUExecutionProvider"])
            self.assertEqual(session.get_inputs()[0].shape[0], "batch")

    def test_an_exported_file_reads_back_into_the_same_function_and_trains_with_frozen_batchnorm(self):
        import torch
        from torch import nn
        from mvgrasp_train import export, import_onnx
        from mvgrasp_train.model import train_mode
        for arch in ("paper", "narrow"):
            model = self.trained_a_little(arch, 48)
            contract = {"input_size_px": 48, "pixel_size_m": 0.0025, "width_scale_m": 0.2,
                        "normalisation": "cube-v1"}
            with tempfile.TemporaryDirectory() as d:
                path = os.path.join(d, "m.onnx")
                export.export(model, 48, path, export.contract_metadata(contract, "t-1", "sim-test"))
                back = import_onnx.from_onnx(path, arch)
                views = np.random.default_rng(3).random((3, 1, 48, 48), dtype=np.float32)
                self.assertLess(export.compare(back, path, views)[0], export.TOLERANCE, arch)
                with torch.no_grad():
                    diff = (back(torch.from_numpy(views)) - model(torch.from_numpy(views))).abs().max().item()
                self.assertLess(diff, 1e-4, arch)
            # Its BatchNorm layers are identities: trained with them frozen
            # (as train.py does for it), a step must not touch their statistics.
            train_mode(back, freeze_batchnorm=True)
            self.assertTrue(back.training)
            before = [m.running_mean.clone() for m in back.modules() if isinstance(m, nn.BatchNorm2d)]
            back(torch.rand(2, 1, 48, 48)).square().mean().backward()
            after = [m.running_mean for m in back.modules() if isinstance(m, nn.BatchNorm2d)]
            self.assertTrue(all(torch.equal(a, b) for a, b in zip(before, after)))


if __name__ == "__main__":
    unittest.main()


@unittest.skipIf(MISSING, REASON)
class Loss(unittest.TestCase):
    def test_positive_weight_scales_only_the_error_at_positive_pixels(self):
        import torch
        from mvgrasp_train.train import weighted_mse
        target = torch.zeros(1, 4, 2, 2)
        target[0, 0, 0, 0] = 0.6  # one positive pixel
        pred = torch.full((1, 4, 2, 2), 0.1)
        plain = weighted_mse(pred, target)
        self.assertAlmostEqual(float(plain), float(((pred - target) ** 2).mean()), places=7)
        # The positive pixel's four channels: 0.5^2 + 3 x 0.1^2; the other 12 entries 0.1^2 each.
        positive, rest = 0.25 + 3 * 0.01, 12 * 0.01
        self.assertAlmostEqual(float(weighted_mse(pred, target, 1.0)), (positive + rest) / 16, places=6)
        self.assertAlmostEqual(float(weighted_mse(pred, target, 10.0)), (10 * positive + rest) / 16, places=6)

    def test_balance_weighs_the_positives_of_views_with_few_of_them_more(self):
        import torch
        from mvgrasp_train.train import weighted_mse
        target = torch.zeros(2, 4, 2, 2)
        target[0, 0, 0, 0] = 0.6  # view 0: one positive pixel
        target[1, 0, :, :1] = 0.6  # view 1: two
        pred = torch.full((2, 4, 2, 2), 0.1)
        positive, rest = 0.25 + 3 * 0.01, 4 * 0.01  # per positive pixel; per other pixel
        # A = 2: view 0's positive counts 2 / 1 times more, view 1's (n = A) do not.
        view0 = 3 * 2 * positive + 3 * rest
        view1 = 2 * 3 * positive + 2 * rest
        self.assertAlmostEqual(float(weighted_mse(pred, target, 3.0, 2.0)), (view0 + view1) / 32, places=6)
        # A = 4: 4 times and twice.
        view0 = 3 * 4 * positive + 3 * rest
        view1 = 2 * 3 * 2 * positive + 2 * rest
        self.assertAlmostEqual(float(weighted_mse(pred, target, 3.0, 4.0)), (view0 + view1) / 32, places=6)
        # A view without positives is unchanged, and 0 turns it off.
        empty = torch.zeros(1, 4, 2, 2)
        self.assertAlmostEqual(float(weighted_mse(pred[:1], empty, 3.0, 4.0)), 0.01, places=7)
        self.assertEqual(float(weighted_mse(pred, target, 3.0, 0.0)), float(weighted_mse(pred, target, 3.0)))

    def test_the_empty_view_weight_counts_only_the_quality_of_views_without_positives(self):
        import torch
        from mvgrasp_train.train import weighted_mse
        target = torch.zeros(2, 4, 2, 2)
        target[0, 0, 0, 0] = 0.6  # view 0: one positive pixel; view 1: none
        pred = torch.full((2, 4, 2, 2), 0.1)
        positive, rest = 0.25 + 3 * 0.01, 4 * 0.01  # per positive pixel; per other pixel
        plain = (3 * positive + 3 * rest + 4 * rest) / 32
        self.assertAlmostEqual(float(weighted_mse(pred, target, 3.0)), plain, places=6)
        # E = 5: view 1's quality channel (4 pixels at 0.01) counts 5 times; its other channels
        # and view 0 are unchanged.
        self.assertAlmostEqual(float(weighted_mse(pred, target, 3.0, 0.0, 5.0)), plain + 4 * 4 * 0.01 / 32,
                               places=6)
        # Alone (positive weight 1) it applies too, and with balance on view 0 it still touches only view 1.
        self.assertAlmostEqual(float(weighted_mse(pred, target, 1.0, 0.0, 5.0)),
                               (positive + 3 * rest + 4 * rest + 4 * 4 * 0.01) / 32, places=6)
        self.assertAlmostEqual(float(weighted_mse(pred, target, 3.0, 4.0, 5.0) - weighted_mse(pred, target, 3.0, 4.0)),
                               4 * 4 * 0.01 / 32, places=6)

    def test_peak_loss_compares_each_view_s_highest_quality_with_its_labels(self):
        import torch
        from mvgrasp_train.train import peak_loss
        target = torch.zeros(2, 3, 3)
        target[0, 1, 1] = 0.8  # view 0: one positive at 0.8; view 1: none
        pred = torch.full((2, 3, 3), 0.1)
        pred[0, 2, 2] = 0.5  # view 0 peaks at 0.5 (elsewhere: the peaks are compared, not the pixels)
        pred[1, 0, 0] = 0.4  # view 1 peaks at 0.4 where it should be 0
        self.assertAlmostEqual(float(peak_loss(pred, target)), ((0.5 - 0.8) ** 2 + 0.4 ** 2) / 2, places=6)
        # Only the peak pixel of each view gets a gradient.
        pred.requires_grad_(True)
        peak_loss(pred, target).backward()
        self.assertEqual(int((pred.grad != 0).sum()), 2)
        self.assertLess(float(pred.grad[0, 2, 2]), 0.0)  # raise view 0's peak
        self.assertGreater(float(pred.grad[1, 0, 0]), 0.0)  # lower view 1's
        self.assertEqual(float(peak_loss(target, target)), 0.0)

    def test_rank_loss_is_minus_the_log_of_the_softmax_share_on_positives(self):
        import math

        import torch
        from mvgrasp_train.train import rank_loss
        logits = torch.zeros(2, 2, 2)
        target = torch.zeros(2, 2, 2)
        target[0, 0, 0] = 0.6  # view 0: one positive of four pixels
        # Equal logits: a quarter of the softmax on the positive.
        self.assertAlmostEqual(float(rank_loss(logits, target)), math.log(4), places=6)
        # View 1 has no positive and counts for nothing, whatever its logits.
        logits[1] = torch.tensor([[5.0, -3.0], [1.0, 2.0]])
        self.assertAlmostEqual(float(rank_loss(logits, target)), math.log(4), places=6)
        # Raising the positive's logit by 2: share e^2 / (e^2 + 3).
        logits[0, 0, 0] = 2.0
        self.assertAlmostEqual(float(rank_loss(logits, target)), -math.log(math.e ** 2 / (math.e ** 2 + 3)), places=6)
        # Its gradient raises the positive and lowers the rest.
        logits.requires_grad_(True)
        rank_loss(logits, target).backward()
        self.assertLess(float(logits.grad[0, 0, 0]), 0.0)
        self.assertTrue(bool((logits.grad[0].flatten()[1:] > 0).all()))
        self.assertTrue(bool((logits.grad[1] == 0).all()))
        # No view with a positive: zero, and still differentiable.
        empty = rank_loss(torch.ones(1, 2, 2, requires_grad=True), torch.zeros(1, 2, 2))
        self.assertEqual(float(empty), 0.0)
        empty.backward()


@unittest.skipIf(MISSING, REASON)
class TeacherTarget(unittest.TestCase):
    MODEL = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "..", "models", "mvgrasp-8.onnx")
    CONTRACT = {"input_size_px": 72, "pixel_size_m": 0.0033333333, "width_scale_m": 0.2, "normalisation": "cube-v1"}

    def test_the_teacher_gives_the_file_s_maps_and_refuses_another_contract(self):
        import onnxruntime
        import torch
        from mvgrasp_train.train import Teacher
        views = torch.from_numpy(np.random.default_rng(5).uniform(0, 1, (2, 1, 72, 72)).astype(np.float32))
        teacher = Teacher(self.MODEL, self.CONTRACT)
        want = onnxruntime.InferenceSession(self.MODEL).run(["maps"], {"views": views.numpy()})[0]
        np.testing.assert_allclose(teacher.maps(views).numpy(), want, atol=1e-6)
        for key, value in (("input_size_px", 96), ("pixel_size_m", 0.005), ("normalisation", "other")):
            with self.assertRaises(SystemExit) as raised:
                Teacher(self.MODEL, {**self.CONTRACT, key: value})
            self.assertIn(f"mvgrasp.{key}", str(raised.exception))


@unittest.skipIf(MISSING, REASON)
class PhysicsTerm(unittest.TestCase):
    def attempts(self, n=6, l=12):
        from mvgrasp_train import physics
        rng = np.random.default_rng(4)
        return physics.Attempts(views=rng.uniform(0, 1, (n, l, l)).astype(np.float32),
                                pixels=rng.integers(0, l, (n, 2)), held=(np.arange(n) % 2).astype(np.float32))

    def test_the_quality_is_read_smoothed_at_the_pixel_as_the_planner_reads_it(self):
        import torch
        from mvgrasp_train import physics
        from mvgrasp_train.train import physics_loss

        class Logits:
            """raw(): the view itself as the quality logit."""
            def raw(self, x):
                return torch.cat([x, torch.zeros_like(x).repeat(1, 3, 1, 1)], dim=1)

        a = self.attempts()
        kernel = physics.gaussian_kernel(1.0)
        picked = np.array([0, 3, 5])
        got = float(physics_loss(Logits(), a, picked, kernel, symmetry=0))
        # The planner's smoothing in numpy: clamped edges, rows then columns.
        r = len(kernel) // 2
        want = []
        for i in picked:
            q = 1 / (1 + np.exp(-a.views[i].astype(np.float64)))
            q = np.pad(q, r, mode="edge")
            q = np.apply_along_axis(lambda row: np.convolve(row, kernel, mode="valid"), 1, q)
            q = np.apply_along_axis(lambda col: np.convolve(col, kernel, mode="valid"), 0, q)
            u, v = a.pixels[i]
            want.append((q[v, u] - a.held[i]) ** 2)
        self.assertAlmostEqual(got, float(np.mean(want)), places=5)
        # A symmetry moves views and pixels together: the same loss.
        for k in range(8):
            self.assertAlmostEqual(float(physics_loss(Logits(), a, picked, kernel, symmetry=k)), got, places=5)

    def test_steps_on_it_move_the_quality_towards_the_outcomes(self):
        import torch
        from mvgrasp_train import physics
        from mvgrasp_train.model import GraspNet
        from mvgrasp_train.train import physics_loss

        torch.manual_seed(0)
        model = GraspNet("narrow")
        model.eval()
        a = self.attempts(n=4, l=72)
        kernel = physics.gaussian_kernel(1.0)
        picked = np.arange(4)
        before = float(physics_loss(model, a, picked, kernel, 0))
        optimiser = torch.optim.Adam(model.parameters(), lr=1e-3)
        for _ in range(20):
            optimiser.zero_grad()
            physics_loss(model, a, picked, kernel, 0).backward()
            optimiser.step()
        self.assertLess(float(physics_loss(model, a, picked, kernel, 0)), 0.5 * before)


@unittest.skipIf(MISSING, REASON)
class Soup(unittest.TestCase):
    """soup.py: the mean of runs' weights, refused across architectures."""

    def save_run(self, root, name, architecture, seed):
        import torch
        from mvgrasp_train import runs
        from mvgrasp_train.model import GraspNet
        torch.manual_seed(seed)
        model = GraspNet(architecture)
        for m in model.modules():  # give BatchNorm statistics that differ between runs too
            if isinstance(m, torch.nn.BatchNorm2d):
                m.running_mean.uniform_(-1, 1)
        run = os.path.join(root, name)
        runs.save(run, architecture, model.state_dict(), True)
        return run, model.state_dict()

    def soup_of_two(self, root, second_architecture):
        """A narrow run and a run of `second_architecture`, souped into root/ab: (status, out, a, b)."""
        from mvgrasp_train import soup
        a = self.save_run(root, "a", "narrow", 0)
        b = self.save_run(root, "b", second_architecture, 1)
        out = os.path.join(root, "ab")
        return soup.main(["--runs", f"{a[0]},{b[0]}", "--out", out]), out, a, b

    def test_the_soup_is_the_mean_and_a_network(self):
        import torch
        from mvgrasp_train import runs
        from mvgrasp_train.model import GraspNet
        with tempfile.TemporaryDirectory() as root:
            status, out, (_, sa), (_, sb) = self.soup_of_two(root, "narrow")
            self.assertEqual(status, 0)
            saved = runs.load(out)
            self.assertTrue(saved["frozen_batchnorm"])
            kernels = 0
            for k, v in saved["state_dict"].items():
                if v.is_floating_point():
                    torch.testing.assert_close(v, (sa[k] + sb[k]) / 2)
                    if v.dim() == 4:  # every kernel differs between the runs, so the mean is a real mix
                        kernels += 1
                        self.assertFalse(torch.equal(sa[k], sb[k]), k)
                else:
                    self.assertTrue(torch.equal(v, sa[k]), k)
            self.assertGreater(kernels, 10)
            model = GraspNet("narrow")
            model.load_state_dict(saved["state_dict"])
            out_maps = model.eval()(torch.rand(2, 1, 72, 72))
            self.assertEqual(tuple(out_maps.shape), (2, 4, 72, 72))

    def test_runs_of_different_architectures_are_refused(self):
        from mvgrasp_train import soup
        with tempfile.TemporaryDirectory() as root:
            status, out, (a, _), _ = self.soup_of_two(root, "paper")
            self.assertEqual(status, 1)
            self.assertFalse(os.path.exists(os.path.join(out, "model.pt")))
            with self.assertRaises(SystemExit):  # one run is no soup
                soup.main(["--runs", a, "--out", out])


@unittest.skipIf(MISSING, REASON)
class RunFolder(unittest.TestCase):
    """runs.py: what train, import_onnx and soup write is what export and train --init read."""

    def test_a_saved_run_loads_back_as_the_same_network(self):
        import torch
        from mvgrasp_train import runs
        from mvgrasp_train.model import GraspNet
        torch.manual_seed(3)
        model = GraspNet("narrow").eval()
        with tempfile.TemporaryDirectory() as root:
            run = os.path.join(root, "nested", "run")  # save makes the folders
            runs.save(run, "narrow", model.state_dict(), True, epochs=7)
            saved = runs.load(run)
        self.assertEqual((saved["architecture"], saved["frozen_batchnorm"], saved["epochs"]), ("narrow", True, 7))
        again = GraspNet(saved["architecture"])
        again.load_state_dict(saved["state_dict"])
        x = torch.rand(2, 1, 72, 72)
        torch.testing.assert_close(again.eval()(x), model(x), rtol=0, atol=0)

    def test_what_is_not_a_run_is_refused_by_name(self):
        import torch
        from mvgrasp_train import export, runs
        with tempfile.TemporaryDirectory() as root:
            with self.assertRaisesRegex(ValueError, "no model.pt"):
                runs.load(root)
            with self.assertRaisesRegex(SystemExit, "--run: .*no model.pt"):
                export.main(["--run", root, "--data", root, "--out", os.path.join(root, "m.onnx"), "--version", "t"])
            path = os.path.join(root, "model.pt")
            with open(path, "wb") as f:
                f.write(b"not a checkpoint")
            with self.assertRaisesRegex(ValueError, "not readable as a run"):
                runs.load(root)
            torch.save({"weights": {}}, path)
            with self.assertRaisesRegex(ValueError, "needs architecture and state_dict"):
                runs.load(root)
            torch.save({"architecture": "huge", "state_dict": {}}, path)
            with self.assertRaisesRegex(ValueError, "unknown architecture 'huge'"):
                runs.load(root)
