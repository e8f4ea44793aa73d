"""Shared pieces of the development scripts (not a test; pytest does not collect it): a benchmark cell
simulated once and kept as a pickle, which configs are white-force drifts, the variant's row, the arguments."""

import pickle
from pathlib import Path

from experiments.simulate.tracking_data import make_cell


def cached_cell(cfg, cache: str | None, key: str) -> dict:
    """``make_cell(cfg)``, read from ``<cache>/<key>.pkl`` when it is there and written there when it is not."""
    path = Path(cache) / f"{key}.pkl" if cache else None
    if path is not None and path.exists():
        return pickle.loads(path.read_bytes())
    cell = make_cell(cfg)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_bytes(pickle.dumps(cell))
    return cell


def white_force(cfg) -> bool:
    """A record under a white force alone: no slosh, no thruster pulses."""
    return not cfg.schedule.slosh and cfg.excitation.disturbance_force_n > 0 and cfg.excitation.thruster_torque_n_m == 0


def white_cells(which: str, seed: int, replicates: int, cache: str | None, keep=None, prefix: str = ""):
    """(label, config, cell) of each record of ``ambient_configs(which, seed, replicates)`` under a white force
    alone whose (label, config) ``keep`` accepts (None: every one), each kept under ``cache`` as
    ``<prefix><which>_<seed>_<replicates>_<index>``."""
    for idx, (label, cfg) in enumerate(ambient_configs(which, seed, replicates).items()):
        if white_force(cfg) and (keep is None or keep(label, cfg)):
            yield label, cfg, cached_cell(cfg, cache, f"{prefix}{which}_{seed}_{replicates}_{idx}")


def white_step_cells(args, prefix: str = ""):
    """:func:`white_cells` of ``args.set``, ``args.seed``, ``args.replicates`` and ``args.cache`` whose label holds
    one of ``args.cells`` (comma-separated) and whose record has a step."""
    import math
    cells = args.cells.split(",")
    for label, cfg, cell in white_cells(args.set, args.seed, args.replicates, args.cache,
                                        lambda label, _: any(c in label for c in cells), prefix):
        if math.isfinite(float(cell["step_time_s"])):
            yield label, cfg, cell


def white_force_drift(cfg) -> bool:
    """A drift under a white force alone."""
    return cfg.schedule.drift is not None and white_force(cfg)


def ambient_configs(which: str, seed: int, replicates: int) -> dict:
    """The white-force and slosh cells of ``tracking_ambient`` (``which="ambient"``) or ``tracking_unseen``'s
    ambient records (``"unseen"``), label → config."""
    if which == "ambient":
        from experiments.benchmarks.tracking_ambient import configs
        return configs(seed, replicates)
    from experiments.benchmarks.tracking_unseen import configs
    return configs(seed, replicates, records="ambient")


def reconvergence_s(t, f, truth, dt: float, step_s: float) -> float:
    """s after the step until every column of ``f`` holds 1 % for 2 s (``score_track``'s rule; NaN: never)."""
    import numpy as np

    from experiments.report.tracking_metrics import score_track
    return score_track(t, f, np.ones(f.shape, bool), 1.0, truth, dt, step_time_s=step_s)["t_reconverge_s"]


def fmt_times(xs) -> str:
    """Times in s joined by "/", "—" for never."""
    import math
    return "/".join("—" if not math.isfinite(x) else f"{x:.1f}" for x in xs)


def step_cells(cfgs: dict, cells: str):
    """(label, cell, Δt, step time, truth) of each config whose label holds one of the comma-separated ``cells``
    and whose record has a step."""
    import math
    for label, cfg in cfgs.items():
        if not any(c in label for c in cells.split(",")):
            continue
        cell = make_cell(cfg)
        st = float(cell["step_time_s"])
        if math.isfinite(st):
            yield label, cell, float(cell["dt_s"]), st, cell["truth_freq_rad_s"]


# the times (s) at which the development scripts print a track's errors
MARKS = (20, 30, 45, 60, 75, 90, 105, 120)


# ``rpem_ambient:two`` (configs/tracker/rpem_ambient_two.yaml) spelled out, so that a script can append options
VARIANT_TWO = ("rpem_ambient:frequency_model=trend+recursions=two+score_reset=true+pair_peaks=true"
               "+rate_test=after_change")


def record_parser(doc: str, cache: bool = True):
    """The arguments every script over the benchmarks' records takes: a seed, the set of records (``ambient``:
    ``tracking_ambient``'s, ``unseen``: ``tracking_unseen``'s), the replicates and (``cache``) a folder of cells."""
    import argparse
    ap = argparse.ArgumentParser(description=doc.splitlines()[0])
    ap.add_argument("seed", type=int)
    ap.add_argument("--set", default="ambient", choices=("ambient", "unseen"))
    ap.add_argument("--replicates", type=int, default=2)
    if cache:
        ap.add_argument("--cache", default=None)
    return ap


def step_parser(doc: str, cells: str = "issue: −7"):
    """:func:`record_parser` (no cache) and the cells by label."""
    ap = record_parser(doc, cache=False)
    ap.add_argument("--cells", default=cells)
    return ap


def print_marks(tr, e, b, bound_name: str, clamp: bool) -> None:
    """A track's signed error ``e`` (relative, samples × modes at the track's times), the bound's 1σ ``b`` and its
    own σ at each of :data:`MARKS` (``clamp``: a mark after the record's end prints its last time; else none),
    then its resets and message."""
    import numpy as np
    for t in MARKS:
        j = np.searchsorted(tr.t_s, t)
        if j >= tr.t_s.size:
            if not clamp:
                continue
            j = tr.t_s.size - 1
        print(f"     {t:4d} s: e % " + " ".join(f"{100 * x:+6.2f}" for x in e[j])
              + f" | {bound_name} % " + " ".join(f"{100 * x:5.2f}" for x in b[j])
              + " | σ % " + " ".join(f"{100 * x:5.2f}" for x in tr.std[j] / tr.frequencies[j]))
    if tr.extra.get("reset_times_s"):
        print("     resets " + " ".join(f"{a:.1f}/m{i + 1}" for a, i in tr.extra["reset_times_s"]))
    print(f"     {tr.message}")
