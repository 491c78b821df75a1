"""``clothtool merge``: join results computed in slices (``analyze --pairs START:STOP``) into one
result equal, dataset by dataset, to a single run over those pairs.

Per-pair datasets are ``/pairs`` and, in the groups ``face``, ``tet``, ``vertex``, ``edge``
and ``summary``, every dataset whose first axis is the part's pair count; they are concatenated in
pair order. ``/frame_vertices`` takes each frame from a part that read it. Everything else
(``/mesh``, ``/frames``, …) must be equal in all parts and is copied once. Parts may be given
in any order but must be slices of the same analysis (same frames, mesh, reference, fields,
dtype and clothtool version) that follow each other without gap or overlap, and together cover
every pair of the analysis (``pair_offset`` 0 to the ``pairs_total`` attribute) unless
``allow_partial``: a Slurm array whose last task failed must not pass for a complete result.

Root attributes: those of the parts (equal in all), ``pair_offset`` of the first part,
``command`` = the merge command, ``created`` = now, ``merged_commands`` = the parts' commands
(of their own parts, for a part that is itself merged).
"""

import datetime
import os

import numpy as np

from clothtool.errors import InputError
from clothtool.io.result import VIEWS, add_aliases, open_result

PAIR_GROUPS = ("face", "tet", "vertex", "edge", "summary")
VARYING_ATTRS = ("command", "created", "pair_offset", "merged_commands")  # differ between parts
BLOCK_BYTES = 64 << 20  # rows copied at a time


def _is_per_pair(h5, name):
    if name == "pairs":
        return True
    ds = h5[name]
    return name.split("/")[0] in PAIR_GROUPS and ds.ndim >= 1 and ds.shape[0] == len(h5["pairs"])


def _datasets(h5):
    """Names of the stored datasets (not the XDMF's views, which are made anew)."""
    names = []
    h5.visititems(lambda name, obj: names.append(name) if hasattr(obj, "shape")
                  and name.split("/")[0] != VIEWS else None)
    return names


def _text(value):
    return value.decode() if isinstance(value, bytes) else value


def _check_parts(parts, allow_partial=False):
    """Sort the open parts by pair offset and check that they are consecutive slices of one
    analysis that cover all its pairs (or, with ``allow_partial``, some). Returns them sorted."""
    def span(h5):
        start = int(h5.attrs.get("pair_offset", 0))
        return start, start + len(h5["pairs"])

    parts = sorted(parts, key=lambda h5: span(h5)[0])
    first = parts[0]
    names = _datasets(first)
    for h5 in parts[1:]:
        for key in set(first.attrs) | set(h5.attrs):
            a, b = first.attrs.get(key), h5.attrs.get(key)
            if key not in VARYING_ATTRS and (a is None or b is None or not np.array_equal(a, b)):
                raise InputError(f"{h5.filename}: attribute {key}={_text(b)!r} differs from "
                                 f"{_text(a)!r} in {first.filename}; not a slice of the same analysis")
        other = _datasets(h5)
        if set(other) != set(names):
            diff = sorted(set(other) ^ set(names))[0]
            owner = h5.filename if diff in other else first.filename
            raise InputError(f"{h5.filename}: datasets differ from {first.filename} "
                             f"({diff} is only in {owner}); slices must store the same fields")
        for name in names:
            a, b = first[name], h5[name]
            if _is_per_pair(first, name):
                if a.shape[1:] != b.shape[1:] or a.dtype != b.dtype:
                    raise InputError(f"{h5.filename}: /{name} is {b.dtype}{b.shape[1:]} per pair, "
                                     f"but {a.dtype}{a.shape[1:]} in {first.filename}")
            elif name != "frame_vertices" and not np.array_equal(a[()], b[()]):
                raise InputError(f"{h5.filename}: /{name} differs from {first.filename}; "
                                 "not a slice of the same sequence")
    for a, b in zip(parts, parts[1:]):
        (a0, a1), (b0, b1) = span(a), span(b)
        if b0 < a1:
            raise InputError(f"{b.filename}: pairs {b0}:{b1} overlap {a.filename} (pairs {a0}:{a1})")
        if b0 > a1:
            raise InputError(f"pairs {a1}:{b0} are missing between {a.filename} (pairs {a0}:{a1}) "
                             f"and {b.filename} (pairs {b0}:{b1})")
    total = first.attrs.get("pairs_total")
    start, stop = span(parts[0])[0], span(parts[-1])[1]
    if not allow_partial and total is not None and (start, stop) != (0, int(total)):
        missing = [f"{a}:{b}" for a, b in ((0, start), (stop, int(total))) if b > a]
        raise InputError(f"pairs {' and '.join(missing)} of the analysis' {int(total)} are in no "
                         f"part ({len(parts)} parts cover {start}:{stop}); a failed or missing "
                         "slice? --allow-partial merges them anyway")
    return parts


def _create_like(dst, name, src, n_rows):
    """An empty dataset like ``src`` (dtype, chunks, compression, fill value) with ``n_rows`` rows."""
    ds = dst.create_dataset(name, shape=(n_rows, *src.shape[1:]), dtype=src.dtype,
                            chunks=src.chunks, compression=src.compression,
                            compression_opts=src.compression_opts, shuffle=src.shuffle,
                            fillvalue=src.fillvalue)
    ds.attrs.update(src.attrs)
    return ds


def _copy_rows(src, dst, at):
    row_bytes = max(1, src.dtype.itemsize * int(np.prod(src.shape[1:], dtype=np.int64)))
    step = max(1, BLOCK_BYTES // row_bytes)
    if src.chunks:
        step = max(src.chunks[0], step - step % src.chunks[0])
    for i in range(0, src.shape[0], step):
        block = src[i:i + step]
        dst[at + i:at + i + len(block)] = block


def merge_results(paths, output, *, command=None, allow_partial=False):
    """Join the slice results ``paths`` into ``output`` (atomic HDF5, plus its XDMF).
    ``allow_partial``: accept parts that cover only some of the analysis' pairs (still
    consecutive). Returns (pair_offset, number of pairs) of the merged result."""
    from clothtool.io.h5 import AtomicH5, check_output_path
    from clothtool.io.xdmf import xdmf_path, xdmf_text

    if not paths:
        raise InputError("merge: no input files")
    check_output_path(output)
    xdmf = xdmf_path(output)
    for path in paths:
        if os.path.abspath(path) == os.path.abspath(output):
            raise InputError(f"{output}: the output is also one of the inputs")
    parts = [open_result(p) for p in paths]
    try:
        parts = _check_parts(parts, allow_partial)
        first = parts[0]
        offset = int(first.attrs.get("pair_offset", 0))
        total = sum(len(h5["pairs"]) for h5 in parts)
        atomic = AtomicH5(output)
        with atomic as dst:
            dst.attrs.update(first.attrs)
            dst.attrs["command"] = command or "clothtool.merge_results"
            dst.attrs["created"] = datetime.datetime.now().astimezone().isoformat(timespec="seconds")
            dst.attrs["merged_commands"] = [
                _text(c) for h5 in parts
                for c in h5.attrs.get("merged_commands", [h5.attrs.get("command", "")])]
            for name in _datasets(first):
                parent = os.path.dirname(name)
                if parent and parent not in dst:
                    dst.require_group(parent).attrs.update(first[parent].attrs)
                src = first[name]
                if _is_per_pair(first, name):
                    ds = _create_like(dst, name, src, total)
                    at = 0
                    for h5 in parts:
                        _copy_rows(h5[name], ds, at)
                        at += h5[name].shape[0]
                elif name == "frame_vertices":
                    ds = _create_like(dst, name, src, src.shape[0])
                    done = set()
                    for h5 in parts:
                        for frame in np.unique(h5["pairs"][:]):
                            if frame >= 0 and frame not in done:
                                ds[frame] = h5[name][frame]
                                done.add(frame)
                else:
                    first.copy(src, dst, name)
            if "summary" in dst:
                add_aliases(dst["summary"])
            atomic.add_sidecar(xdmf, xdmf_text(dst, os.path.basename(output)))  # renamed with it
    finally:
        for h5 in parts:
            h5.close()
    return offset, total
