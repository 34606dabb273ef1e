"""A run folder's network: RUN_DIR/model.pt.

`train`, `import_onnx` and `soup` write it; `export --run`, `train --init`
and `soup` read it. What they share is the architecture, the weights and
whether BatchNorm is frozen (folded imports are); a writer may add more
(`train`: epochs and seconds, `import_onnx`: the file it read).
"""

import os

MODEL = "model.pt"


def save(run_dir, architecture, state_dict, frozen_batchnorm, **extra):
    """Write RUN_DIR/model.pt (the folder is made if missing)."""
    import torch
    os.makedirs(run_dir, exist_ok=True)
    state = {k: v.detach().cpu() for k, v in state_dict.items()}
    torch.save({"architecture": architecture, "state_dict": state, "frozen_batchnorm": bool(frozen_batchnorm),
                **extra}, os.path.join(run_dir, MODEL))


def load(run_dir):
    """RUN_DIR/model.pt as a dict with at least `architecture`, `state_dict`
    and `frozen_batchnorm`; ValueError naming the folder when it holds no
    run this package wrote."""
    import torch

    from .model import ARCHITECTURES
    path = os.path.join(run_dir, MODEL)
    if not os.path.isfile(path):
        raise ValueError(f"{run_dir}: no {MODEL} (a folder written by train, import_onnx or soup)")
    try:
        saved = torch.load(path, map_location="cpu")
    except Exception as e:  # a truncated or foreign file: say which
        raise ValueError(f"{path}: not readable as a run ({type(e).__name__}: {e})") from e
    if not isinstance(saved, dict) or "state_dict" not in saved or "architecture" not in saved:
        raise ValueError(f"{path}: not a run's model (needs architecture and state_dict)")
    if saved["architecture"] not in ARCHITECTURES:
        raise ValueError(f"{path}: unknown architecture {saved['architecture']!r} (known: {', '.join(ARCHITECTURES)})")
    saved.setdefault("frozen_batchnorm", False)
    return saved
