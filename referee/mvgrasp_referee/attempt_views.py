"""Physics outcomes of the planner's grasps with the views they came from,
for the network to learn from (`--attempt-views DIR`).

Per episode, `attempts_SCENARIO_CAMERA_SEED_eEPISODE.npy` (float32
`[n, L, L]`: the view each tried grasp came from, exactly as the network
read it) and a `.json` beside it (per row the quality peak `pixel` `[u, v]`,
the grasp's `angle_rad` in the view (closing direction from +u towards +v),
the `outcome`: "ok" when the object reached the bin, else the referee's
failure name, and whether the row is an `alternative`: a grasp ranked below
the episode's own, tried from the same state, which was then put back);
`manifest.json` holds the model contract. This is the format of `sim eval
--attempt-views` (training/mvgrasp_train/physics.py reads both); train
with `--physics-failures empty,dropped-carry,slip-shake` for the referee's
names.
"""

import json
import os

import numpy as np

FORMAT = "mvgrasp-attempt-views-2"
HELD = "ok"


class Recorder:
    """One episode's rows."""

    def __init__(self):
        self.views, self.rows = [], []

    def add(self, plan, grasp, rank, outcome, step, alternative, target):
        """A tried grasp of `plan` (a `Planner.plan` answer with views); False
        when its view is not in the answer (nothing recorded)."""
        view = plan.get("views", {}).get((grasp["object"], grasp["view"]))
        if view is None:
            return False
        self.views.append(view)
        self.rows.append({"step": step, "rank": rank, "alternative": alternative, "view": grasp["view"],
                          "pixel": list(grasp["pixel"]), "angle_rad": round(grasp.get("angle_rad", 0.0), 4),
                          "quality": round(grasp["quality"], 4),
                          "width_mm": round(grasp["width_m"] * 1000.0, 1),
                          "outcome": HELD if outcome == "success" else outcome, "target": target})
        return True

    def write(self, folder, scenario, camera, seed, episode, size_px):
        """The episode's two files (none without rows); returns the row count."""
        if not self.rows:
            return 0
        os.makedirs(folder, exist_ok=True)
        stem = os.path.join(folder, f"attempts_{scenario}_{camera}_{seed}_e{episode}")
        views = np.asarray(self.views, dtype="<f4").reshape(len(self.rows), size_px, size_px)
        np.save(stem + ".npy", views)
        with open(stem + ".json", "w") as f:
            json.dump(self.rows, f)
        return len(self.rows)


def write_manifest(folder, info, contract, rows, meta):
    """`manifest.json` for `rows` rows written by the episodes of a run."""
    os.makedirs(folder, exist_ok=True)
    manifest = {"format": FORMAT, "source": "referee", "model_version": info["model_version"],
                "contract": contract, "attempts": rows, **meta}
    with open(os.path.join(folder, "manifest.json"), "w") as f:
        json.dump(manifest, f, indent=1)
