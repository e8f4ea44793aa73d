"""The white-force drift records against a bound that is not told the rate — a development table, not a test
(pytest does not collect it).

    python tests/methods/tracking/dev/_line_bound_dev.py SEED [--set ambient|unseen] [--replicates 2]
        [--trackers "next_era,rpem_ambient:two"] [--rates 0.001,0.01]

On ``tracking_ambient``'s (``--set ambient``) or ``tracking_unseen``'s (``--set unseen``) white-force drift
records (a line over the whole record: every drift ends at or after the record's end), the unknown-force bound as
the benchmarks score it (its walk matched to the schedule: on a drift each step has the drift's size, so it is
the bound of a tracker told the rate) beside the **unknown-rate** bound (``pcrb_force.unknown_force_pcrb`` with
``rate_std``: each frequency a line with an unknown constant rate, prior N(0, (rate·ω₀)²) for each ``--rates``,
in relative units per second). Per record and tracker: the median over replicates of × each bound (median |e|
after 30 s over the bound's median 1σ after 30 s, as the benchmarks'), and each mode's × the first unknown-rate
bound; the ratio of the two bounds' medians.
"""

import os
import sys
from pathlib import Path

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
sys.path[:0] = [str(Path(__file__).resolve().parents[4])]

import numpy as np  # noqa: E402
from _cells import record_parser, white_force_drift  # noqa: E402

import methods  # noqa: E402
from experiments.benchmarks import tracking_ambient, tracking_unseen  # noqa: E402
from experiments.benchmarks.tracking_beats import parse_row  # noqa: E402
from experiments.simulate.pcrb_force import unknown_force_pcrb  # noqa: E402
from experiments.simulate.plant import build_plant  # noqa: E402
from experiments.simulate.timevarying import modal_model  # noqa: E402
from experiments.simulate.tracking_data import RATE_PRIOR_REL_PER_S, make_cell  # noqa: E402

SETTLE_S = 30.0


def drift_configs(which: str, seed: int, replicates: int):
    cfgs = (tracking_ambient.configs(seed, replicates) if which == "ambient"
            else tracking_unseen.configs(seed, replicates, records="ambient"))
    for label, cfg in cfgs.items():
        if white_force_drift(cfg):
            yield label, cfg


def line_bound(cfg, cell, rate_rel: float) -> np.ndarray:
    """The unknown-rate bound with the prior rate ``rate_rel``·ω per s: the cell's own at the stored rate."""
    if rate_rel == RATE_PRIOR_REL_PER_S and "pcrb_unknown_rate_std_rad_s" in cell:
        return cell["pcrb_unknown_rate_std_rad_s"]
    model = modal_model(build_plant(cfg.plant))
    w = cell["truth_freq_rad_s"]
    column = "force_body_y" if cfg.excitation.disturbance_at == "body" else "force_tip"
    return unknown_force_pcrb(model, w, cell["modal_state"].astype(float), cfg.dt_s, float(cell["noise_std_m_s2"]),
                              cell["prior_rad_s"], force_std_n=cfg.excitation.disturbance_force_n,
                              force_input=column, u=cell["inputs"].astype(float), rate_std=rate_rel * w[0])


def main() -> None:
    ap = record_parser(__doc__, cache=False)
    ap.add_argument("--trackers", default="next_era,rpem_ambient:two")
    ap.add_argument("--rates", default="0.001,0.01")
    args = ap.parse_args()
    rates = [float(x) for x in args.rates.split(",")]
    for label, cfg in drift_configs(args.set, args.seed, args.replicates):
        cell = make_cell(cfg)
        dt, truth = float(cell["dt_s"]), cell["truth_freq_rad_s"]
        bounds = {"walk": cell["pcrb_unknown_force_std_rad_s"]}
        bounds.update({f"line {100 * r:g} %/s": line_bound(cfg, cell, r) for r in rates})
        late = np.arange(truth.shape[0]) * dt >= SETTLE_S
        med = {k: float(np.median(b[:, late] / truth[late])) for k, b in bounds.items()}
        print(f"## {args.seed} | {label} | bound medians % " + ", ".join(f"{k} {100 * v:.3f}" for k, v in med.items())
              + f" | line/walk {med[f'line {100 * rates[0]:g} %/s'] / med['walk']:.2f}", flush=True)
        for spec in args.trackers.split(","):
            name, opts = parse_row(spec)
            xs = {k: [] for k in bounds}
            per = []
            for r in range(args.replicates):
                tr = methods.track(name, cell["accel_m_s2"][r], dt, cell["prior_rad_s"][r], **opts)
                k = np.round(tr.t_s / dt).astype(int)
                e = np.abs(tr.frequencies - truth[k]) / truth[k]
                on = tr.t_s >= SETTLE_S
                for key, b in bounds.items():
                    xs[key].append(np.nanmedian(e[on]) / np.median(b[r][k][on] / truth[k][on]))
                lb = bounds[f"line {100 * rates[0]:g} %/s"][r][k][on] / truth[k][on]
                per.append(np.nanmedian(e[on], axis=0) / np.median(lb, axis=0))
            print(f"   {spec:24s} " + " | ".join(f"× {key} {np.median(v):.2f} (" + "/".join(f"{x:.2f}" for x in v) + ")"
                                               for key, v in xs.items())
                  + " | per mode × line " + "/".join(f"{x:.1f}" for x in np.median(per, axis=0)), flush=True)


if __name__ == "__main__":
    main()
