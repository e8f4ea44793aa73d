"""A probe of hostile inputs and faults: each case is a user's command, run as a real subprocess.

    PYTHONPATH=$PWD nice -n 5 .venv/bin/python tests/probe/hostile.py [--jobs 2] [--only GROUP] [--out FILE]

Not a pytest module (pytest collects ``test_*.py``; this file is run by hand): it takes minutes, and it
reports rather than asserts. Each case runs in a scratch folder of its own (the fixtures it reads live
elsewhere) and gets one verdict:

- ``refused``: exit status 2 and exactly one line of output, starting ``error:`` (a good refusal);
- ``accepted``: exit status 0;
- ``traceback``: a Python traceback anywhere in the output;
- ``unclear``: any other failure (several lines, another exit status, no ``error:``);
- ``hang``: the command did not end within its time bound.

A case says what it expects (``refuse``, ``accept``, or ``either`` where both are sound), and is a problem
when it ends in a traceback, an unclear refusal or a hang, when it is refused with files left behind in its
folder, when it is accepted and should not be (or refused and should not be), or when its own check fails
(a marker file an injection would create, a dataset not regenerated, a run lost or duplicated). The counts
are printed and the table written to ``results/bench/faults.md`` (``--out``).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import dataclasses
import math
import os
import shlex
import shutil
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
import zipfile
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[2]
PY = sys.executable
SNAKEMAKE = str(Path(PY).parent / "snakemake")
MARK = "PWNED"                        # the file an injection that executed code would create
NYQUIST = math.pi / 0.02


@dataclasses.dataclass
class Case:
    group: str
    name: str
    argv: list[str]
    expect: str = "refuse"                                     # refuse | accept | either
    setup: Callable[[Path], None] | None = None
    check: Callable[[Path, subprocess.CompletedProcess], str | None] | None = None
    timeout: float = 120
    env: dict = dataclasses.field(default_factory=dict)
    ignore: tuple[str, ...] = (".snakemake",)                  # Snakemake's own metadata folder
    run: Callable[[Case, Path], subprocess.CompletedProcess] | None = None   # a fault: its own script
    index: int = 0
    verdict: str = ""
    problem: str = ""
    seconds: float = 0.0
    first_line: str = ""


# ---- running and judging -----------------------------------------------------------------------------------

def environment(extra: dict | None = None) -> dict:
    env = {k: v for k, v in os.environ.items() if not k.startswith("MLFLOW_")}
    env.update(PYTHONPATH=str(ROOT), OPENBLAS_NUM_THREADS="1", OMP_NUM_THREADS="1",
               PATH=f"{Path(PY).parent}{os.pathsep}{os.environ.get('PATH', '')}")
    env.update(extra or {})
    return env


def files_in(folder: Path, ignore: tuple[str, ...]) -> set[str]:
    out = set()
    for path in folder.rglob("*"):
        rel = path.relative_to(folder)
        if rel.parts[0] in ignore:
            continue
        if path.is_file() or path.is_symlink():
            out.add(str(rel))
    return out


def run_case(case: Case, scratch: Path) -> Case:
    work = scratch / f"{case.index:03d}-{case.group}"
    work.mkdir(parents=True)
    if case.setup:
        case.setup(work)
    before = files_in(work, case.ignore)
    t0 = time.perf_counter()
    try:
        if case.run:
            try:
                proc = case.run(case, work)
            except (OSError, ValueError, KeyError, sqlite3.Error) as exc:
                proc = subprocess.CompletedProcess([], 1, "", f"probe: the fault could not be set up: {exc}\n")
        else:
            proc = subprocess.run(case.argv, cwd=work, capture_output=True, text=True, timeout=case.timeout,
                                  env=environment(case.env), errors="replace")
    except subprocess.TimeoutExpired:
        case.seconds = time.perf_counter() - t0
        case.verdict, case.problem = "hang", f"no end within {case.timeout:.0f} s"
        return case
    case.seconds = time.perf_counter() - t0
    text = (proc.stdout or "") + (proc.stderr or "")
    lines = [line for line in text.splitlines() if line.strip()]
    case.first_line = next((line for line in lines if line.startswith("error:")), lines[0] if lines else "")
    if "Traceback (most recent call last)" in text:
        case.verdict = "traceback"
        case.first_line = lines[-1] if lines else ""
    elif proc.returncode == 0:
        case.verdict = "accepted"
    elif proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("error:"):
        case.verdict = "refused"
    else:
        case.verdict = "unclear"
        case.first_line = f"exit {proc.returncode}, {len(lines)} lines: " + (case.first_line or "")
    problems = []
    if case.verdict in ("traceback", "unclear"):
        problems.append(case.verdict)
    if case.verdict == "accepted" and case.expect == "refuse":
        problems.append("wrongly accepted")
    if case.verdict == "refused" and case.expect == "accept":
        problems.append("wrongly refused")
    if case.verdict != "accepted":
        left = sorted(files_in(work, case.ignore) - before)
        if left:
            problems.append(f"leftovers: {', '.join(left[:3])}{' ...' if len(left) > 3 else ''}")
    if (work / MARK).exists() or (scratch / MARK).exists():
        problems.append("an injection executed code")
    if case.check:
        found = case.check(work, proc)
        if found:
            problems.append(found)
    case.problem = "; ".join(problems)
    return case


# ---- fixtures: valid inputs, and their corrupt twins ----------------------------------------------------------

def write_csv(path: Path, n: int = 256, dt: float = 0.02, header: str = "t,accel") -> None:
    t = dt * np.arange(n)
    y = np.exp(-0.05 * t) * (np.cos(20.3 * t) + 0.5 * np.cos(56.7 * t))
    path.write_text(header + "\n" + "".join(f"{a:.6f},{b:.9e}\n" for a, b in zip(t, y, strict=True)))


def csv_text(rows, header="t,accel", newline="\n") -> str:
    return newline.join([header, *rows]) + newline


def good_rows(n=256, dt=0.02):
    t = dt * np.arange(n)
    y = np.exp(-0.05 * t) * (np.cos(20.3 * t) + 0.5 * np.cos(56.7 * t))
    return [f"{a:.6f},{b:.9e}" for a, b in zip(t, y, strict=True)]


def make_fixtures(fix: Path) -> None:
    fix.mkdir(parents=True, exist_ok=True)
    env = environment()
    subprocess.run([PY, "-m", "experiments.jobs.make_dataset", "noise_ug=1000", "n_samples=64", "replicates=2",
                    f"out={fix / 'cell.npz'}"], check=True, cwd=fix, env=env, capture_output=True)
    write_csv(fix / "good.csv")
    rows = good_rows()
    csvs = {
        "empty.csv": "",
        "header_only.csv": "t,accel\n",
        "one_row.csv": csv_text(rows[:1]),
        "seven_rows.csv": csv_text(rows[:7]),
        "text_cell.csv": csv_text(rows[:100] + ["2.0,abc"] + rows[101:]),
        "nan_cell.csv": csv_text(rows[:100] + ["2.0,nan"] + rows[101:]),
        "inf_cell.csv": csv_text(rows[:100] + ["2.0,inf"] + rows[101:]),
        "huge_value.csv": csv_text(rows[:100] + ["2.0,1e300"] + rows[101:]),
        "time_backwards.csv": csv_text(rows[:50] + [rows[51], rows[50]] + rows[52:]),
        "time_repeated.csv": csv_text(rows[:50] + [rows[50], rows[50]] + rows[52:]),
        "time_gap.csv": csv_text(rows[:100] + rows[140:]),
        "time_descending.csv": csv_text(rows[::-1]),
        "three_columns.csv": csv_text([r + ",0.0" for r in rows], header="t,a,b"),
        "semicolon.csv": csv_text([r.replace(",", ";") for r in rows], header="t;accel"),
        "tab.csv": csv_text([r.replace(",", "\t") for r in rows], header="t\taccel"),
        "crlf.csv": csv_text(rows, newline="\r\n"),
        "bom.csv": "\ufeff" + csv_text(rows),
        "comment_lines.csv": "# logger v1\n" + csv_text(rows),
        "time_only.csv": csv_text([r.split(",")[0] for r in rows], header="t"),
        "all_zero.csv": csv_text([r.split(",")[0] + ",0.0" for r in rows]),
        "all_nan.csv": csv_text([r.split(",")[0] + ",nan" for r in rows]),
        "non_ascii_header.csv": csv_text(rows, header="temps,accél [g]"),
        "quoted.csv": csv_text(['"' + r.replace(",", '","') + '"' for r in rows], header='"t","accel"'),
        "missing_value.csv": csv_text(rows[:100] + ["2.0,"] + rows[101:]),
        "ragged.csv": csv_text(rows[:100] + ["2.0,1.0,3.0"] + rows[101:]),
        "trailing_blank.csv": csv_text(rows) + "\n\n\n",
        "formula.csv": csv_text(rows[:100] + ["2.0,=cmd|' /C calc'!A0"] + rows[101:]),
        "no_header.csv": "\n".join(rows) + "\n",
        "decimal_comma.csv": csv_text([r.replace(",", ";").replace(".", ",") for r in rows], header="t;accel"),
        "long_line.csv": "t,accel\n" + "1" * 1_000_000 + "\n",
        "huge_time.csv": csv_text([f"{1e300 * (i + 1):.6e},{i}" for i in range(64)]),
        "mesure_été.csv": csv_text(rows),
        "my file.csv": csv_text(rows),
    }
    for name, text in csvs.items():
        (fix / name).write_text(text, encoding="utf-8")
    (fix / "utf16.csv").write_text(csv_text(rows), encoding="utf-16")
    (fix / "garbage.csv").write_bytes(np.random.default_rng(1).bytes(4096))
    (fix / "nul_bytes.csv").write_bytes(b"t,accel\n" + b"\x00" * 512)
    (fix / "xlsx.csv").write_bytes(b"PK\x03\x04" + np.random.default_rng(2).bytes(2000))
    (fix / "a_folder.csv").mkdir(exist_ok=True)
    loop = fix / "loop.csv"
    if not loop.is_symlink():
        loop.symlink_to(fix / "loop.csv")
    # datasets: corrupt twins of a valid cell
    cell = (fix / "cell.npz").read_bytes()
    (fix / "half.npz").write_bytes(cell[: len(cell) // 2])
    (fix / "zero.npz").write_bytes(b"")
    (fix / "garbage.npz").write_bytes(np.random.default_rng(3).bytes(4096))
    (fix / "a_csv.npz").write_text(csv_text(rows))
    with np.load(fix / "cell.npz") as z:
        arrays = {k: z[k] for k in z.files}
    tampered = dict(arrays)
    key = next(k for k in arrays if arrays[k].dtype.kind == "f" and arrays[k].size > 1)
    tampered[key] = arrays[key] * 1.0001
    np.savez(fix / "tampered.npz", **tampered)
    missing = {k: v for k, v in arrays.items() if k != key}
    np.savez(fix / "missing_key.npz", **missing)
    empty = {k: (v[:0] if v.ndim >= 1 and v.shape[0] == 2 else v) for k, v in arrays.items()}
    np.savez(fix / "zero_records.npz", **empty)
    np.savez(fix / "pickled.npz", **arrays, extra=np.array([{"a": 1}], dtype=object))
    with zipfile.ZipFile(fix / "zipbomb_like.npz", "w") as zf:
        zf.writestr("y.npy", b"\x93NUMPY" + b"\x00" * 100)
    (fix / "a_folder.npz").mkdir(exist_ok=True)
    (fix / "evil.yaml").write_text("# @package _global_\nname: evil\nmethod: {name: fft}\n")


def repo_copy(work: Path, grid: str | None = None, name: str = "bad") -> None:
    """A scratch copy of the workflow in ``work``: Snakefile and configs copied, code linked."""
    shutil.copy(ROOT / "Snakefile", work / "Snakefile")
    shutil.copytree(ROOT / "configs", work / "configs")
    if (ROOT / "profiles").is_dir():         # a default workflow profile would print its banner first
        shutil.copytree(ROOT / "profiles", work / "profiles")
    for part in ("experiments", "methods"):
        (work / part).symlink_to(ROOT / part)
    if grid is not None:
        (work / "configs" / "grid" / f"{name}.yaml").write_text(grid)


def run_sh_copy(work: Path, grid: str, name: str) -> None:
    """A workflow copy that runs through ``./run.sh``, the user's entry point (its lock clearing and its
    --rerun-incomplete), with this environment seen as run.sh's installed .venv."""
    repo_copy(work, grid, name)
    shutil.copy(ROOT / "run.sh", work / "run.sh")
    shutil.copy(ROOT / "pyproject.toml", work / "pyproject.toml")
    venv_bin = work / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    for exe in ("python", "snakemake"):
        (venv_bin / exe).symlink_to(Path(PY).parent / exe)
    (work / ".venv" / ".installed").touch()


TINY = "name: tiny\nnoise_ug: [1000]\nn_samples: [64]\nreplicates: 2\nseed: 7\nmethods: [fft, akf]\n"


# ---- the cases ------------------------------------------------------------------------------------------------

def py(module: str, *args: str) -> list[str]:
    return [PY, "-m", module, *args]


def identify(*args: str) -> list[str]:
    return py("experiments.jobs.identify", *args)


def cases(fix: Path) -> list[Case]:
    out: list[Case] = []
    add = out.append
    cell = f"data.dataset={fix / 'cell.npz'}"
    off = "runlog.enabled=false"

    # CSV measurement files (method=fft with a prior: the quickest complete job)
    csv_expect = {"good.csv": "accept", "crlf.csv": "accept", "bom.csv": "accept", "trailing_blank.csv": "accept",
                  "non_ascii_header.csv": "either",    # 'temps' is no time column's name: two channels
                  "mesure_été.csv": "accept", "my file.csv": "either",
                  "three_columns.csv": "either", "tab.csv": "either", "semicolon.csv": "either",
                  "comment_lines.csv": "either", "quoted.csv": "either", "no_header.csv": "either",
                  "time_gap.csv": "refuse", "all_zero.csv": "either"}
    for name in sorted(p.name for p in fix.iterdir() if p.suffix == ".csv"):
        add(Case("csv", name, identify("method=fft", f"data.path={fix / name}", "prior=[20,56]", off),
                 expect=csv_expect.get(name, "refuse")))
    add(Case("csv", "nonexistent", identify("method=fft", "data.path=nosuch.csv", "prior=[20,56]", off)))
    add(Case("csv", "/dev/null", identify("method=fft", "data.path=/dev/null", "prior=[20,56]", off)))
    add(Case("csv", "a .txt file", identify("method=fft", f"data.path={fix / 'good.csv'}x", "prior=[20,56]", off)))
    good = f"data.path={fix / 'good.csv'}"
    for opt, expect in [("data.units=furlongs", "refuse"), ("data.units=mm/s2", "accept"), ("data.units=g", "accept"),
                        ("data.channel=nosuch", "refuse"), ("data.channel=99", "refuse"),
                        ("data.channel=-1", "refuse"), ("data.dt=0", "refuse"), ("data.dt=-1", "refuse"),
                        ("data.dt=nan", "refuse"), ("data.dt=inf", "refuse"), ("data.dt=abc", "refuse"),
                        ("data.dt=0.02", "accept"), ("data.dt=1e-300", "refuse"), ("data.nosuch=1", "refuse")]:
        add(Case("csv", opt, identify("method=fft", good, "prior=[20,56]", opt, off), expect=expect))

    # priors, on a simulated cell (4 modes, dt = 0.02 s)
    bad_priors = ["[1,2]", "[]", "[0,20,22,56]", "[-3,20,22,56]", "[nan,20,22,56]", "[inf,20,22,56]",
                  "[3,20,20,56]", "[56,22,20,3]", f"[3,20,22,{NYQUIST:.10f}]", "[3,20,22,200]", "[3,20,22,1e300]",
                  "abc", "[[1,2],[3,4]]", "[[3,20],[22,56]]", "[1,2", "null", "'[3,20,22,x]'", "5",
                  "[3,20,22,56,57]", "'${oc.env:HOME}'", "[1e-300,20,22,56]", "[true,20,22,56]"]
    for method in ("pem", "akf"):
        for prior in bad_priors:
            # null: the dataset's own prior (the default); 1e-300: below one cycle per record is allowed (the
            # paper's 20-sample records are shorter than mode 1's period), the method says it is not determined
            expect = "either" if prior in ("null", "[1e-300,20,22,56]") else "refuse"
            add(Case("prior", f"{method} prior={prior}", identify(f"method={method}", cell, f"prior={prior}", off),
                     expect=expect))
        add(Case("prior", f"{method} prior=paper", identify(f"method={method}", cell, "prior=[3.5,19,23,55]", off),
                 expect="accept", timeout=300))
    for std in ["-1", "[nan,1,1,1]", "[1,2]", "0", "abc", "[inf,1,1,1]", "[-1,1,1,1]"]:
        add(Case("prior", f"pem prior_std_rad_s={std}", identify("method=pem", cell, f"prior_std_rad_s={std}", off)))

    # method options
    opts = [("pem", "method.options.n_starts=-1"), ("pem", "method.options.n_starts=0"),
            ("pem", "method.options.n_starts=1000000000"), ("pem", "method.options.n_starts=abc"),
            ("pem", "method.options.n_starts=1.5"), ("pem", "method.options.max_iterations=-1"),
            ("pem", "method.options.max_iterations=0"), ("pem", "method.options.max_iterations=1000000000"),
            ("pem", "method.options.nosuch=1"), ("pem", "+method.options.nosuch=1"),
            ("pem", "~method.options.n_starts"), ("pem", "method.options=5"), ("pem", "method.options.n_starts=null"),
            ("akf", "method.options.rd=-1"), ("akf", "method.options.rd=nan"), ("akf", "method.options.rd=inf"),
            ("akf", "method.options.measurement=foo"), ("pll", "method.options.filter_order=0"),
            ("pll", "method.options.filter_order=-1"), ("pll", "method.options.filter_order=1000"),
            ("fft", "method.options.zero_pad_factor=0"), ("fft", "method.options.zero_pad_factor=-1"),
            ("fft", "method.options.zero_pad_factor=1000000000"), ("wkf", "method.options.nosuch=1")]
    # accepted by design: fft computes at most max_fft_length points whatever the padding asked (the peaks are
    # refined on the padded grid); a Chebyshev input filter of any order is designed as stable sections
    by_design = {"method.options.zero_pad_factor=1000000000", "method.options.filter_order=1000"}
    for method, opt in opts:
        add(Case("options", f"{method} {opt}", identify(f"method={method}", cell, opt, off),
                 expect="either" if opt in by_design else "refuse"))
    add(Case("options", "akf measurement=acceleration", identify("method=akf", cell,
             "method.options.measurement=acceleration", off), expect="accept"))
    for method in ["nosuch", "", "pem_nosuch", "PEM", "../../x", "pem,fft", "pem;touch PWNED"]:
        add(Case("options", f"method={method}", identify(f"method={method}", cell, off)))

    # dataset cells: make_dataset's overrides
    base = {"noise_ug": "1000", "n_samples": "64", "replicates": "2"}
    for key, value in [("noise_ug", "0"), ("noise_ug", "-1"), ("noise_ug", "nan"), ("noise_ug", "inf"),
                       ("noise_ug", "abc"), ("noise_ug", "1e308"), ("n_samples", "7"), ("n_samples", "0"),
                       ("n_samples", "-64"), ("n_samples", "64.5"), ("n_samples", "1000000000000"),
                       ("replicates", "0"), ("replicates", "-1"), ("replicates", "1000000000"),
                       ("replicates", "1.5"), ("seed", "-1"), ("seed", "36893488147419103232"), ("seed", "abc"),
                       ("dt_s", "0"), ("dt_s", "-0.02"), ("dt_s", "nan"), ("dt_s", "0.06"), ("dt_s", "100"),
                       ("bias_m_s2", "nan"), ("bias_m_s2", "inf"), ("nosuch", "1"), ("scenario.nosuch", "1"),
                       ("scenario.damping", "[-1]")]:
        args = {**base, key: value}
        add(Case("dataset", f"make_dataset {key}={value}",
                 py("experiments.jobs.make_dataset", *(f"{k}={v}" for k, v in args.items()), "out=c.npz")))
    for outp, setup in [("out=dir/", None), ("out=", None), ("out=/proc/version/c.npz", None),
                        ("out=file/c.npz", lambda w: (w / "file").write_text("x")),
                        ("out=c.txt", None)]:
        add(Case("dataset", f"make_dataset {outp}",
                 py("experiments.jobs.make_dataset", *(f"{k}={v}" for k, v in base.items()), outp),
                 expect="either" if outp == "out=c.txt" else "refuse", setup=setup))
    add(Case("dataset", "make_dataset valid", py("experiments.jobs.make_dataset",
             *(f"{k}={v}" for k, v in base.items()), "out=c.npz"), expect="accept"))
    for name in ["half.npz", "zero.npz", "garbage.npz", "a_csv.npz", "tampered.npz", "missing_key.npz",
                 "zero_records.npz", "pickled.npz", "zipbomb_like.npz", "a_folder.npz", "nosuch.npz"]:
        add(Case("dataset", f"identify on {name}", identify("method=fft", f"data.dataset={fix / name}", off)))
    add(Case("dataset", "identify on a valid cell", identify("method=fft", cell, off), expect="accept"))
    add(Case("dataset", "identify on /etc/passwd", identify("method=fft", "data.dataset=/etc/passwd", off)))

    # grids, through snakemake (a dry run: every grid refusal comes before any job)
    g = "name: bad\nnoise_ug: [1000]\nn_samples: [64]\nreplicates: 2\nseed: 1\nmethods: [fft]\n"
    grids = {
        "noise nan": g.replace("[1000]", "[.nan]"), "noise inf": g.replace("[1000]", "[.inf]"),
        "noise negative": g.replace("[1000]", "[-1]"), "noise zero": g.replace("[1000]", "[0]"),
        "noise text": g.replace("[1000]", "[loud]"), "2 GiB cell": g.replace("replicates: 2", "replicates: 1000000")
        .replace("[64]", "[2048]"), "replicates 0": g.replace("replicates: 2", "replicates: 0"),
        "n_samples 7": g.replace("[64]", "[7]"), "unknown method": g.replace("[fft]", "[nosuch]"),
        "no methods": g.replace("[fft]", "[]"), "name mismatch": g.replace("name: bad", "name: other"),
        "not a mapping": "- 1\n- 2\n", "yaml syntax": g.replace("[1000]", "[1000,"), "empty file": "",
        "python tag": g + "x: !!python/object/apply:os.system ['touch PWNED']\n",
        "override nosuch": g + "method_overrides: {fft: [method.options.nosuch=1]}\n",
        "override n_starts -1": g.replace("[fft]", "[pem]") + "method_overrides: {pem: [method.options.n_starts=-1]}\n",
        "override n_starts 1e9": g.replace("[fft]", "[pem]")
        + "method_overrides: {pem: [method.options.n_starts=1000000000]}\n",
        "override other method": g + "method_overrides: {pll: [method.options.filter_order=2]}\n",
        "override unbalanced": g + "method_overrides: {fft: ['prior=[1,2']}\n",
        "override env": g + "method_overrides: {fft: ['prior=${oc.env:HOME}']}\n",
        "override hydra": g + "method_overrides: {fft: ['hydra.run.dir=/proc/x']}\n",
        "seed negative": g.replace("seed: 1", "seed: -1"), "dt nan": g + "dt_s: .nan\n",
        "dt zero": g + "dt_s: 0\n", "dt Nyquist": g + "dt_s: 0.06\n",
        "damping negative": g + "scenarios:\n  - damping: [-0.01]\n",
        "gap too large": g + "scenarios:\n  - gap_rad_s: [40]\n", "unknown key": g + "nosuch: 1\n",
        "duplicate key": g + "seed: 2\n", "bad name": g.replace("name: bad", "name: ../bad"),
        "bias inf": g + "bias_m_s2: .inf\n", "methods not a list": g.replace("[fft]", "fft"),
        "variant unknown": g.replace("[fft]", "['pem:nosuch']"),
    }
    for label, text in grids.items():
        # a duplicate key: YAML's last wins; hydra.run.dir: a batch job has no run folder, so it is unused
        expect = "either" if label in ("duplicate key", "override hydra") else "refuse"
        add(Case("grid", label, [SNAKEMAKE, "-n", "--cores", "1", "results/bad/README.md"], expect=expect,
                 setup=lambda w, t=text: repo_copy(w, t), timeout=180))
    for target in ["results/nosuch/README.md", "results/../README.md", "results/tiny/../../etc/passwd",
                   "nosuchrule", "results/tiny/data/nosuch.npz", "results/tiny/identify/nosuch"]:
        add(Case("grid", f"target {target}", [SNAKEMAKE, "-n", "--cores", "1", target],
                 setup=lambda w: repo_copy(w, TINY, "tiny"), timeout=180))
    add(Case("grid", "valid tiny grid (dry run)", [SNAKEMAKE, "-n", "--cores", "1", "results/tiny/README.md"],
             expect="accept", setup=lambda w: repo_copy(w, TINY, "tiny"), timeout=180))

    # command lines
    for args, expect in [(["--nosuch"], "refuse"), (["nosuch"], "refuse"), (["method=pem", "method=fft", cell, off],
                         "refuse"), (["method=fft", cell, f"data.path={fix / 'good.csv'}", off], "refuse"),
                         (["method=fft", cell, "x" * 100_000], "refuse"), (["method=fft", cell, "out=", off], "either"),
                         (["method=fft", cell, "=1", off], "refuse"), (["method=fft", cell, "a..b=1", off], "refuse"),
                         (["method=fft", cell, "'unbalanced", off], "refuse"),
                         (["--cfg", "job", "method=pem"], "accept"),
                         (["--help"], "accept"), (["-m", "method=fft,nosuch", cell, off], "refuse"),
                         (["method=fft", cell, "out=/proc/version/x.csv", off], "refuse"),
                         (["method=fft", cell, f"hydra.run.dir={fix / 'cell.npz'}/run", off], "refuse"),
                         (["method=fft", cell, f"out={'d/' * 2000}x.csv", off], "refuse"),
                         (["method=fft", f"data.path={fix / 'mesure_été.csv'}", "prior=[20,56]", off], "accept")]:
        add(Case("cli", "identify " + " ".join(a[:40] for a in args if not a.startswith("data.dataset")),
                 identify(*args), expect=expect))
    for args in [["dataset", "not json"], ["dataset", "[]"], ["dataset", "[[1]]"], ["nosuch", "[[]]"],
                 ["identify", '[["method=fft"]]', "--workers", "0"], ["identify", '[["method=fft"]]', "--workers", "x"],
                 ["dataset", '[["noise_ug=-1", "out=c.npz"]]'], []]:
        add(Case("cli", "batch " + " ".join(args), py("experiments.jobs.batch", *args)))
    for args in [[], ["data", "nosuch", "--out", "x"], ["run", "tracking", "--tracker", "nosuch", "--data", "nosuch",
                                                          "--out", "x"], ["score", "tracking_smoke", "--out", "x"]]:
        add(Case("cli", "track_job " + " ".join(args), py("experiments.jobs.track_job", *args)))
    add(Case("cli", "runlog on a missing table", py("experiments.runlog.identify_runs", "--grid", "x", "--out",
                                                    "r.json", "--", "nosuch.csv")))
    add(Case("cli", "runlog on a non-table", py("experiments.runlog.identify_runs", "--grid", "x", "--out", "r.json",
                                                "--", str(fix / "good.csv"))))
    add(Case("cli", "aggregate on a missing table", py("experiments.report.aggregate", "--grid", "x", "--out", "o",
                                                       "--page", "o/p.md", "--", "nosuch.csv")))
    add(Case("cli", "reproduce experiment=nosuch", py("experiments.jobs.reproduce", "experiment=nosuch",
                                                      "runlog.enabled=false")))
    add(Case("cli", "tune tuning=nosuch", py("experiments.tuning.tune", "tuning=nosuch")))
    add(Case("cli", "compare --methods nosuch", py("experiments.tuning.compare", "--methods", "nosuch",
                                                   "--cells", "10:256")))
    add(Case("cli", "compare --cells x", py("experiments.tuning.compare", "--methods", "fft", "--cells", "x")))

    # security: paths and injections (an injection that ran would create PWNED)
    for args, expect in [(["data.path=/etc/passwd", "prior=[20,56]"], "refuse"),
                         (["data.path=$(touch PWNED)", "prior=[20,56]"], "refuse"),
                         (["data.path=`touch PWNED`", "prior=[20,56]"], "refuse"),
                         ([cell, "out=x.csv; touch PWNED"], "either"),
                         ([cell, "out=$(touch PWNED).csv"], "either"),
                         ([cell, "method.options.zero_pad_factor=${oc.env:HOME}"], "refuse"),
                         ([cell, "+method._target_=os.system"], "refuse"),
                         ([cell, "method._target_=os.system"], "refuse"),
                         ([cell, "hydra/launcher=nosuch"], "refuse"),
                         ([cell, "hydra.searchpath=[file:///nonexistent]"], "either"),
                         ([cell, f"method=../../../../../..{fix}/evil"], "refuse"),
                         ([cell, "out=../../../tmp/hostile_escape_probe.csv"], "either"),
                         ([cell, "+hydra.job.env_set.LD_PRELOAD=/tmp/x.so"], "either"),
                         ([cell, "data.dataset=../../../../../../etc/shadow"], "refuse"),
                         ([cell, "out=/dev/full"], "refuse"),
                         ([f"data.path={fix / 'formula.csv'}", "prior=[20,56]"], "refuse"),
                         ([cell, "prior=\"__import__('os').system('touch PWNED')\""], "refuse"),
                         ([cell, "method.options.zero_pad_factor=\"eval('1')\""], "refuse"),
                         ([cell, "grid_name=../../etc"], "either"),
                         ([cell, "out=" + "é" * 300 + ".csv"], "refuse")]:
        add(Case("security", " ".join(a[:60] for a in args if not a.startswith("data.dataset=/")),
                 identify("method=fft", *args, off), expect=expect))
    add(Case("security", "grid with a python tag, real run", [SNAKEMAKE, "--cores", "1", "results/bad/README.md"],
             setup=lambda w: repo_copy(w, grids["python tag"]), timeout=180))

    out += fault_cases(fix)
    return out


# ---- faults: a tiny grid run for real, then killed, deleted from, truncated, shared ----------------------------

def snakemake_run(work: Path, *args: str, env: dict | None = None, timeout: float = 900):
    """``./run.sh snakemake --cores 2 ...`` in a copy made by :func:`run_sh_copy`."""
    return subprocess.run(["./run.sh", "snakemake", "--cores", "2", *args], cwd=work, capture_output=True,
                          text=True, timeout=timeout, env=environment(env))


def store_runs(db: Path) -> tuple[int, int]:
    """(runs, distinct run keys) among the active runs of a SQLite MLflow store."""
    with sqlite3.connect(db) as con:
        n = con.execute("select count(*) from runs where lifecycle_stage='active'").fetchone()[0]
        keys = con.execute("select count(distinct value) from tags join runs using(run_uuid) where "
                           "tags.key='run_key' and lifecycle_stage='active'").fetchone()[0]
    return n, keys


def comparison(work: Path, grid: str = "tiny") -> str:
    path = work / "results" / grid / "tables" / "comparison.csv"
    if not path.exists():
        return ""
    lines = path.read_text().splitlines()
    col = lines[0].split(",").index("median_runtime_s")
    return "\n".join(",".join(v for i, v in enumerate(line.split(",")) if i != col) for line in lines)


def as_proc(ok: bool, message: str) -> subprocess.CompletedProcess:
    """A fault's outcome as one command's: exit 0 when the workflow did the right thing."""
    return subprocess.CompletedProcess([], 0 if ok else 1, "" if ok else f"fault: {message}\n", "")


def fault_cases(fix: Path) -> list[Case]:
    out = []
    ref: dict = {}

    def baseline(case, work):
        proc = snakemake_run(work, "results/tiny/README.md")
        ref["work"] = work
        ref["table"] = comparison(work)
        ref["data"] = {p.name: p.read_bytes() for p in (work / "results" / "tiny" / "data").glob("*.npz")}
        return proc

    def deleted_dataset(case, work):
        base = ref["work"]
        (victim,) = (base / "results" / "tiny" / "data").glob("*.npz")
        victim.unlink()
        proc = snakemake_run(base, "results/tiny/README.md")
        if proc.returncode:
            return proc
        ok = victim.exists() and victim.read_bytes() == ref["data"][victim.name] and comparison(base) == ref["table"]
        return as_proc(ok, "the deleted dataset was not regenerated bit for bit, or the table changed")

    def killed(case, work):
        p = subprocess.Popen(["./run.sh", "snakemake", "--cores", "2", "results/tiny/README.md"], cwd=work,
                             stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, env=environment(),
                             start_new_session=True)
        deadline = time.time() + 300
        while time.time() < deadline and not list((work / "results" / "tiny").glob("identify/*/*.csv")):
            time.sleep(0.2)
        os.killpg(p.pid, signal.SIGKILL)
        p.wait()
        proc = snakemake_run(work, "results/tiny/README.md")
        if proc.returncode:
            return proc
        n, keys = store_runs(work / "results" / "mlflow.db")
        same = comparison(work) == ref["table"]
        return as_proc(n == keys == 3 and same, f"after kill -9 and rerun: {n} runs, {keys} keys, same table: {same}")

    def shared_store(case, work):
        db = work / "shared.db"
        env = {"MLFLOW_TRACKING_URI": f"sqlite:///{db}"}
        procs, dirs = [], []
        for i, seed in enumerate((7, 8)):
            d = work / f"wf{i}"
            d.mkdir()
            name = f"tiny{'ab'[i]}"
            run_sh_copy(d, TINY.replace("seed: 7", f"seed: {seed}").replace("tiny", name), name)
            dirs.append(d)
            procs.append(subprocess.Popen(["./run.sh", "snakemake", "--cores", "1",
                                           f"results/{name}/README.md"], cwd=d, stdout=subprocess.PIPE,
                                          stderr=subprocess.STDOUT, text=True, env=environment(env)))
        outs = [p.communicate(timeout=900)[0] for p in procs]
        if any(p.returncode for p in procs):
            return subprocess.CompletedProcess([], 1, "".join(outs), "")
        n, keys = store_runs(db)
        return as_proc(n == keys == 6, f"two workflows on one store: {n} runs, {keys} distinct keys (want 6)")

    def truncated(fraction):
        def run(case, work):
            base = ref["work"]
            db = base / "results" / "mlflow.db"
            data = db.read_bytes()
            db.write_bytes(data[: int(len(data) * fraction)])
            try:
                return subprocess.run(identify("method=fft", f"data.dataset={fix / 'cell.npz'}"), cwd=base,
                                      capture_output=True, text=True, timeout=300, env=environment())
            finally:
                leftover = [p for p in (base / "results" / "runs").glob("*")] if (base / "results" / "runs").exists() \
                    else []
                ref[f"runs_{fraction}"] = leftover
                db.write_bytes(data)
        return run

    def truncated_workflow(case, work):
        base = ref["work"]
        db = base / "results" / "mlflow.db"
        original = db.read_bytes()
        db.write_bytes(original[: len(original) // 2])
        for page in ("mlflow_runs.json", "README.md"):        # the track step's outputs: it must run again
            (base / "results" / "tiny" / page).unlink(missing_ok=True)
        try:
            return snakemake_run(base, "results/tiny/README.md")
        finally:
            db.write_bytes(original)

    def inputs(work):
        shutil.copy(fix / "cell.npz", work / "cell.npz")
        write_csv(work / "my.csv")

    def read_only(args):
        def run(case, work):
            script = (f"mount --bind {work} {work} && mount -o remount,bind,ro {work} && cd {work} && "
                      f"{shlex.join([PY, *args])}")
            return subprocess.run(["unshare", "-m", "sh", "-c", script], capture_output=True, text=True,
                                  timeout=120, env=environment())
        return run

    out.append(Case("fault", "tiny grid run", [], expect="accept", run=baseline, timeout=900,
                    setup=lambda w: run_sh_copy(w, TINY, "tiny")))
    out.append(Case("fault", "a deleted dataset, rerun", [], expect="accept", run=deleted_dataset, timeout=900))
    out.append(Case("fault", "store truncated to half: a job logged to MLflow", [], run=truncated(0.5), timeout=300,
                    check=lambda w, p: "run folder written" if ref.get("runs_0.5") else None))
    out.append(Case("fault", "store truncated to zero: a job logged to MLflow", [], run=truncated(0.0), timeout=300,
                    check=lambda w, p: "run folder written" if ref.get("runs_0.0") else None))
    out.append(Case("fault", "store truncated to half: the workflow", [], run=truncated_workflow, timeout=900))
    out.append(Case("fault", "kill -9 and rerun", [], expect="accept", run=killed, timeout=1200,
                    setup=lambda w: run_sh_copy(w, TINY, "tiny")))
    out.append(Case("fault", "two workflows, one store", [], expect="accept", run=shared_store, timeout=1200))
    for label, args in [("identify a cell", ["-m", "experiments.jobs.identify", "method=fft", "data.dataset=cell.npz"]),
                        ("identify a cell, no tracking", ["-m", "experiments.jobs.identify", "method=fft",
                                                          "data.dataset=cell.npz", "runlog.enabled=false"]),
                        ("identify a CSV", ["-m", "experiments.jobs.identify", "method=fft", "data.path=my.csv",
                                            "prior=[20,56]", "runlog.enabled=false"]),
                        ("make a dataset", ["-m", "experiments.jobs.make_dataset", "noise_ug=10", "n_samples=64",
                                            "replicates=2", "out=results/c.npz"])]:
        out.append(Case("fault", f"read-only folder: {label}", [], run=read_only(args), timeout=120, setup=inputs))
    return out


# ---- main --------------------------------------------------------------------------------------------------

def table(done: list[Case]) -> str:
    counts = Counter(c.verdict for c in done)
    problems = [c for c in done if c.problem]
    rows = ["# Hostile inputs and faults", "",
            "`PYTHONPATH=$PWD nice -n 5 .venv/bin/python tests/probe/hostile.py` (tests/probe/hostile.py says "
            "how each case is judged).", "",
            f"{len(done)} cases: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items()))
            + f"; problems: {len(problems)}.", "",
            "| group | case | expect | verdict | problem | first line | s |", "|---|---|---|---|---|---|---|"]
    for c in done:
        cell = (c.first_line or "")[:160].replace("|", "\\|")
        name = c.name[:80].replace("|", "\\|")
        rows.append(f"| {c.group} | `{name}` | {c.expect} | {c.verdict} | {c.problem.replace('|', '/')} | "
                    f"{cell} | {c.seconds:.1f} |")
    return "\n".join(rows) + "\n"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--only", help="a group: csv, prior, options, dataset, grid, cli, security, fault")
    parser.add_argument("--out", default=str(ROOT / "results" / "bench" / "faults.md"))
    args = parser.parse_args()
    scratch = Path(tempfile.mkdtemp(prefix="hostile-"))
    fix = scratch / "fixtures"
    make_fixtures(fix)
    todo = [c for c in cases(fix) if args.only in (None, c.group)]
    for i, case in enumerate(todo):
        case.index = i
    faults = [c for c in todo if c.group == "fault"]
    inputs = [c for c in todo if c.group != "fault"]
    t0 = time.time()
    done = []
    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        for case in pool.map(lambda c: run_case(c, scratch / "cases"), inputs):
            done.append(case)
            print(f"{case.group:8s} {case.verdict:9s} {case.problem[:50]:50s} {case.name[:60]}", flush=True)
    for case in faults:                 # in order: each builds on the tiny grid run first
        done.append(run_case(case, scratch / "cases"))
        print(f"{case.group:8s} {case.verdict:9s} {case.problem[:50]:50s} {case.name[:60]}", flush=True)
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(table(done))
    counts = Counter(c.verdict for c in done)
    problems = Counter(p.split(":")[0] for c in done for p in c.problem.split("; ") if p)
    print(f"\n{len(done)} cases in {time.time() - t0:.0f} s: "
          + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    print("problems: " + (", ".join(f"{k} {v}" for k, v in sorted(problems.items())) or "none"))
    print(f"table: {args.out}; scratch: {scratch}")


if __name__ == "__main__":
    main()
