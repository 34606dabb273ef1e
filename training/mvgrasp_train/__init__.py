"""Training for the mvgrasp grasp network (see training/README.md).

The numpy-only modules (`dataset`, `augment`, `metric`) are what CI tests;
`model`, `train` and `export` need PyTorch.
"""
