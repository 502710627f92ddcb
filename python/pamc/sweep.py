"""pamc's sweeps in parts: the cells of `pamc robustness` run in parallel, here or on a cluster's
workers through dask.distributed (docs/PYTHON.md, "Sweeps on a cluster").

    from dask.distributed import Client
    import pamc.sweep
    summary = pamc.sweep.robustness("robustness", client=Client("tcp://scheduler:8786"))

The workers need pamc importable (the deb, or PYTHONPATH=build/python on a shared file system); each part
returns its cells as a dict, so only out_dir, on the machine that calls, is written.
"""

import shutil
import tempfile

from . import _pamc

__all__ = ["calibrate", "robustness"]


def _part(settings, index, count, pairs_of=None, threads=1, verbose=False):
    """Part index/count of a phase's cells: the dict `pamc robustness --shard` writes as cells.json.
    Its identification records go to a folder of its own, removed after."""
    work = tempfile.mkdtemp(prefix="pamc_part_")
    try:
        return _pamc._robustness_cells(settings, index, count, work, threads, pairs_of, verbose)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _phase(client, settings, parts, pairs_of, threads, verbose):
    """The phase's parts: one in this process without a client, else `parts` tasks on the client's workers."""
    if client is None:
        return [_part(settings, 1, 1, pairs_of, threads, verbose)]
    futures = [client.submit(_part, settings, i, parts, pairs_of, pure=False) for i in range(1, parts + 1)]
    return client.gather(futures)


def robustness(out_dir="robustness", *, client=None, parts=None, plant=None, model=None, only_axes=(), seed=1,
               pairs=True, score_from="common", duration_scale=1.0, fit_method="ga", figures=True, threads=2,
               verbose=False, **gains):
    """`pamc robustness` in parts: returns the summary.json it writes into out_dir (the same files as the
    command: axis_*.csv, grid.csv, heat maps, summary.txt, the models identified, cells.json).

    client: a dask.distributed Client - each phase (the axes, then the pairs grid chosen from them) runs as
    `parts` tasks (default: the workers' threads), one thread each; None: in this process on `threads`.
    plant, model, only_axes, seed, pairs, score_from, gains (kp=..., ki=...): as the command's options;
    duration_scale and fit_method ("ga", "lm") as its --duration-scale and --method."""
    settings = _pamc._robustness_settings(plant=plant, model=model, only_axes=list(only_axes), seed=seed, pairs=pairs,
                                          score_from=score_from, duration_scale=duration_scale,
                                          fit_method=fit_method, **gains)
    if client is not None and parts is None:
        parts = sum(client.nthreads().values())
    if parts is not None and parts < 1:
        raise ValueError("parts: at least 1")
    axes = _phase(client, settings, parts, None, threads, verbose)
    summary, merged = _pamc._robustness_merge(axes, out_dir, figures and not pairs, verbose)
    if summary["pairs_pending"]:
        grid = _phase(client, settings, parts, merged, threads, verbose)
        summary, _ = _pamc._robustness_merge(grid, out_dir, figures, verbose)
    elif figures and pairs:  # no grid was due (fewer than two axes): the figures of the axes
        summary, _ = _pamc._robustness_merge([merged], out_dir, figures, verbose)
    return summary


def _calibration_plant(ki_grid, values):
    """One candidate plant of the calibration (a task): its points, its runs in a folder removed after."""
    work = tempfile.mkdtemp(prefix="pamc_plant_")
    try:
        return _pamc._calibration_plant(ki_grid, values, work)
    finally:
        shutil.rmtree(work, ignore_errors=True)


def calibrate(out_dir="calibration", *, client=None, ki_grid=(), axes=(), passes=2, threads=2, verbose=False):
    """`pamc calibrate`'s coordinate search (docs/CALIBRATION.md); each step's candidate plants run in
    parallel - as tasks on the client's workers, or without a client on `threads` threads here (their runs
    then in out_dir). Returns {"table": the Markdown table the command prints, "points": every point tried
    (plant_values, ki, summary, distance), "best": the index of the chosen one}.

    ki_grid: the readings of ki to try (default: the command's); axes: the free parameters searched (names,
    default all)."""
    ki_grid = [float(k) for k in ki_grid]
    evaluate = None
    if client is not None:
        def evaluate(batch):
            futures = [client.submit(_calibration_plant, ki_grid, list(values), pure=False) for values in batch]
            return client.gather(futures)
    return _pamc._calibrate(ki_grid, list(axes), passes, threads, out_dir, evaluate, verbose)
