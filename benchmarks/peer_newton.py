"""NVIDIA Newton's own cloth-twist example (VBD with self-contact) on the CPU, for bench_peers.py.

    .venv-newton/bin/python benchmarks/peer_newton.py SPEC.npz OUT.npz

Run by ``python -m benchmarks peers`` with the Python of ``.venv-newton`` (``python3 -m venv
.venv-newton && .venv-newton/bin/pip install newton warp-lang usd-core``), so it imports
newton and warp only, never clothtool. SPEC.npz: ``frames``. The example (a 50 × 50 sheet whose
two ends turn in opposite directions, 60 fps) runs as it comes, after an untimed example
stepped once (warp compiles its kernels). OUT.npz: ``positions`` (frames + 1, N, 3), ``faces``,
``cpu`` (s: the process's CPU time of the frames, every thread), ``substeps`` and
``iterations`` (VBD iterations per substep).
"""

import sys
import time

import numpy as np
import warp as wp

wp.config.quiet = True
import newton  # noqa: E402
import newton.viewer  # noqa: E402
from newton.examples.cloth import example_cloth_twist as twist  # noqa: E402


class Args:  # the example reads nothing from its arguments
    pass


def example(frames):
    return twist.Example(newton.viewer.ViewerNull(num_frames=frames), Args())


if __name__ == "__main__":
    frames = int(np.load(sys.argv[1])["frames"])
    wp.set_device("cpu")
    example(1).step()  # compiles the kernels, untimed
    ex = example(frames)
    positions = [ex.state_0.particle_q.numpy().astype(np.float64)]
    cpu = 0.0
    for _ in range(frames):
        started = time.process_time()
        ex.step()
        wp.synchronize()
        cpu += time.process_time() - started
        positions.append(ex.state_0.particle_q.numpy().astype(np.float64))
    np.savez(sys.argv[2], positions=np.array(positions), faces=np.asarray(ex.faces, np.int64),
             cpu=cpu, substeps=ex.sim_substeps, iterations=ex.iterations)
    print(f"newton twist: {len(positions[0])} vertices, {frames} frames, {cpu:.2f} s CPU")
