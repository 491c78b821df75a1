"""clothtool: measure and produce cloth deformation.

Library API (the CLI is a thin layer over these)::

    import clothtool
    clothtool.analyze_sequence("frames/", "out.h5")      # per-triangle deformation → HDF5
    mesh = clothtool.read_ply("frame_0001.ply")           # our own PLY reader
    mesh = clothtool.read_obj("frame_0001.obj")           # and OBJ reader (same mesh type)
    clothtool.simulate("config.yaml")                     # implicit cloth simulation → PLY frames
    clothtool.sweep("base.yaml", "runs", grid={"material.stretch": [1e3, 1e4]})  # many of them

Heavy modules (numba, h5py) are imported on first use so that ``clothtool --help`` starts fast.
"""

__version__ = "0.1.0"

_LAZY = {
    "analyze_sequence": ("clothtool.analysis.sequence", "analyze_sequence"),
    "read_ply": ("clothtool.io.ply", "read_ply"),
    "write_ply": ("clothtool.io.ply", "write_ply"),
    "read_obj": ("clothtool.io.obj", "read_obj"),
    "read_mesh": ("clothtool.io.frames", "read_mesh"),
    "discover_frames": ("clothtool.io.frames", "discover_frames"),
    "simulate": ("clothtool.sim.api", "simulate"),
    "load_config": ("clothtool.sim.model.config", "load_config"),
    "sweep": ("clothtool.sweeps.api", "sweep"),
    "sweep_report": ("clothtool.sweeps.report", "sweep_report"),
    "fit": ("clothtool.sweeps.motion_fit", "fit"),
}

from clothtool.errors import ClothtoolError, InputError, NumericalError  # noqa: E402

__all__ = ["ClothtoolError", "InputError", "NumericalError", "__version__", *_LAZY]


def __getattr__(name):
    if name in _LAZY:
        import importlib

        module, attr = _LAZY[name]
        return getattr(importlib.import_module(module), attr)
    raise AttributeError(f"module 'clothtool' has no attribute {name!r}")
