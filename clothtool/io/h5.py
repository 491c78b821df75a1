"""Writing analysis results to HDF5 without ever leaving a partial file.

The file is written under a temporary name in the target folder and renamed over
the target only when complete; on any error, Ctrl-C or SIGTERM the temporary file
is removed and an existing output stays byte-identical. Field datasets are chunked
one pair per chunk row so that a pair is read without touching the others.
"""

import os

import numpy as np

from clothtool.errors import ClothtoolError, InputError
from clothtool.io.atomic import finish, temporary_name

CHUNK_BYTES = 4 << 20  # upper bound on one chunk (HDF5's own limit is 4 GiB)


def check_output_path(path):
    """Fail before any work when ``path`` cannot be written: a folder, a missing or
    read-only folder."""
    path = os.fspath(path)
    if os.path.isdir(path):
        raise InputError(f"{path}: output path is a folder")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError(f"{path}: output folder {folder} does not exist")
    if not os.access(folder, os.W_OK | os.X_OK):
        raise InputError(f"{path}: output folder {folder} is not writable")
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise InputError(f"{path}: output file is not writable")


def check_not_an_input(path, inputs):
    """Fail when the output would replace one of the ``inputs`` (frames, a reference mesh)."""
    target = os.path.realpath(path)
    for item in inputs:
        if os.path.realpath(item) == target:
            raise InputError(f"{path}: output path is also an input ({item}); "
                             "it would be overwritten")


def parse_compression(spec):
    """'none' → {} ; 'gzip' or 'gzip=LEVEL' → h5py keyword arguments (with shuffle)."""
    spec = (spec or "none").strip().lower()
    if spec == "none":
        return {}
    name, _, level = spec.partition("=")
    if name == "gzip":
        if not level:
            return {"compression": "gzip", "compression_opts": 4, "shuffle": True}
        if level.isdigit() and 0 <= int(level) <= 9:
            return {"compression": "gzip", "compression_opts": int(level), "shuffle": True}
    raise InputError(f"{spec!r} is not 'none', 'gzip' or 'gzip=0..9'", keyword="compression")


class AtomicH5:
    """``with AtomicH5(path) as f:`` gives an ``h5py.File`` on a temporary name that
    becomes ``path`` only if the block completes; :meth:`add_sidecar` files (an XDMF)
    are renamed with it, right after it, or removed with it. An ``OSError`` while
    writing (a full disk, say) becomes an :class:`InputError` naming ``path``."""

    def __init__(self, path):
        self.path = os.path.abspath(os.fspath(path))
        self.tmp = temporary_name(self.path)
        self.file = None
        self._renames = [(self.tmp, self.path)]

    def __enter__(self):
        import h5py

        try:
            self.file = h5py.File(self.tmp, "w")
        except BaseException as exc:
            finish(self._renames, ok=False)
            if isinstance(exc, OSError):
                raise self._write_error(exc) from exc
            raise
        return self.file

    def add_sidecar(self, path, text):
        """Write ``text`` to a temporary name beside ``path`` now; it becomes ``path``
        when the HDF5 file is complete."""
        tmp = temporary_name(path)
        self._renames.append((tmp, os.path.abspath(os.fspath(path))))
        with open(tmp, "w", encoding="utf-8") as fh:
            fh.write(text)

    def __exit__(self, exc_type, exc, tb):
        try:
            finish(self._renames, ok=exc_type is None, close=self.file.close)
        except OSError as error:
            raise self._write_error(error) from error
        if isinstance(exc, OSError) and not isinstance(exc, ClothtoolError):
            raise self._write_error(exc) from exc
        return False

    def _write_error(self, exc):
        return InputError(f"{self.path}: cannot write: {exc.strerror or exc}")


def create_pair_dataset(group, name, n_pairs, item_shape, dtype, compression, fillvalue=None):
    """A (P, *item_shape) dataset chunked as (1, rows, ...) with a chunk ≤ CHUNK_BYTES;
    unwritten elements read as ``fillvalue``."""
    item_shape = tuple(item_shape)
    if 0 in item_shape:  # nothing to chunk or compress, e.g. /edge/* of a mesh without interior edges
        return group.create_dataset(name, shape=(n_pairs, *item_shape), dtype=dtype, fillvalue=fillvalue)
    row_bytes = int(np.prod(item_shape[1:], dtype=np.int64)) * np.dtype(dtype).itemsize
    rows = max(1, min(item_shape[0], CHUNK_BYTES // max(row_bytes, 1))) if item_shape[0] else 1
    chunks = (1, rows, *item_shape[1:])
    return group.create_dataset(name, shape=(n_pairs, *item_shape), dtype=dtype,
                                chunks=chunks, fillvalue=fillvalue, **compression)


def write_row(dataset, index, values):
    """``dataset[index] = values`` for a dataset made by :func:`create_pair_dataset`.

    Uncompressed rows go straight into their chunks (``write_direct_chunk``: no HDF5
    selection or conversion machinery, about twice as fast as ``__setitem__`` for
    megabyte rows); anything else takes the ordinary path."""
    values = np.asarray(values)
    chunks = dataset.chunks
    if (dataset.compression is not None or chunks is None or values.dtype != dataset.dtype
            or not values.flags.c_contiguous or values.shape != dataset.shape[1:]):
        dataset[index] = values
        return
    rows = chunks[1]
    zeros = (0,) * (values.ndim - 1)
    for start in range(0, values.shape[0], rows):
        block = values[start:start + rows]
        if block.shape[0] < rows:  # the last chunk of the row extends past the data
            block = np.concatenate([block, np.zeros((rows - block.shape[0], *block.shape[1:]),
                                                    block.dtype)])
        dataset.id.write_direct_chunk((index, start, *zeros), block.data)


class PairWriter:
    """Writes each pair's arrays on a background thread while the next pair is computed.

    Double-buffered: :meth:`buffers` returns a set of arrays that is not being written
    (waiting for the write that used it two pairs ago); :meth:`write` queues it. The
    numba kernels release the GIL, so computing pair p+1 overlaps writing pair p.
    Errors of the writer thread are raised in the caller at the next call or at exit.
    """

    def __init__(self, datasets, make_buffers):
        from concurrent.futures import ThreadPoolExecutor

        self.datasets = datasets
        self._sets = [make_buffers(), make_buffers()]
        self._pending = [None, None]
        self._turn = 0
        self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="clothtool-h5")

    def buffers(self):
        pending = self._pending[self._turn]
        if pending is not None:
            pending.result()
        return self._sets[self._turn]

    def write(self, index, buffers, prepare=None):
        """Queue ``buffers`` for row ``index``; ``prepare()``, if given, runs on the writer
        thread first (per-pair summaries and averages: work that overlaps the next pair)."""
        self._pending[self._turn] = self._pool.submit(self._write, index, buffers, prepare)
        self._turn ^= 1

    def _write(self, index, buffers, prepare):
        if prepare is not None:
            prepare()
        for name, dataset in self.datasets.items():
            write_row(dataset, index, buffers[name])

    def __enter__(self):
        return self

    def __exit__(self, exc_type, exc, tb):
        self._pool.shutdown(wait=True, cancel_futures=exc_type is not None)
        if exc_type is None:
            for pending in self._pending:
                if pending is not None:
                    pending.result()
        return False
