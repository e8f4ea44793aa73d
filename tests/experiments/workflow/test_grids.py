"""The workflow's Python (experiments/workflow/: grids, targets, command_line) without Snakemake: a grid's
cells, its jobs' command lines, and every refusal as one ``error:`` line naming the grid file and the value,
before any job runs."""

from __future__ import annotations

import shutil
from pathlib import Path

import pytest

from experiments.workflow import targets
from experiments.workflow.command_line import (
    check_target,
    command_line_targets,
    renamed_rules,
    requested_grids,
    unknown_rule_targets,
)
from experiments.workflow.grids import GridError, Grids, method_config
from experiments.workflow.tracking import TRACKING_GRIDS, tracking_grid
from experiments.workflow.triggers import resolved_config

ROOT = Path(__file__).resolve().parents[3]
GRID = "name: {name}\nnoise_ug: [10, 1000]\nn_samples: [64]\nreplicates: 2\nseed: 5\nmethods: [fft, akf]\n"


@pytest.fixture(scope="module")
def root(tmp_path_factory):
    """A checkout's configs with test grids only (the repository's configs/grid/ is never written)."""
    root = tmp_path_factory.mktemp("checkout")
    shutil.copytree(ROOT / "configs", root / "configs", ignore=shutil.ignore_patterns("grid"))
    (root / "configs" / "grid").mkdir()
    return root


def workflow_with(root, name, text) -> Grids:
    (root / "configs" / "grid" / f"{name}.yaml").write_text(text)
    return Grids(root)


def test_a_plain_grid_gives_one_dataset_and_one_table_per_cell_and_method(root):
    wf = workflow_with(root, "plain", GRID.format(name="plain"))
    assert wf.cells("plain") == ["noise10ug_n64", "noise1000ug_n64"]
    assert targets.result_files(wf, "plain") == [f"results/plain/identify/{m}/noise{u}ug_n64.csv"
                                        for m in ("fft", "akf") for u in (10, 1000)]
    assert targets.dataset_jobs(wf, "plain")[1] == ["noise_ug=1000", "n_samples=64", "replicates=2", "seed=5",
                                                    "dt_s=0.02", "bias_m_s2=0.0",
                                                    "out=results/plain/data/noise1000ug_n64.npz"]
    assert targets.identify_jobs(wf, "plain", "akf")[0] == [
        "method=akf", "data.dataset=results/plain/data/noise10ug_n64.npz",
        "out=results/plain/identify/akf/noise10ug_n64.csv", "grid_name=plain", "runlog.enabled=false"]
    assert targets.grid_targets("plain") == ["results/plain/README.md", "results/plain/mlflow_runs.json"]


def test_a_measurement_cell_runs_only_the_methods_whose_options_have_it(root):
    """akf and wkf have the option ``measurement`` (their Options), fft has not: asked of the registry."""
    wf = workflow_with(root, "meas", GRID.format(name="meas").replace("[fft, akf]", "[fft, akf, \"pem:paper\"]")
                       + "scenarios:\n  - {measurement: [acceleration]}\n")
    cell = "noise10ug_n64_acceleration"
    assert cell in wf.cells("meas")
    assert targets.method_cells(wf, "meas", "akf") == wf.cells("meas")
    assert targets.method_cells(wf, "meas", "fft") == [] == targets.method_cells(wf, "meas", method_config("pem:paper"))
    assert targets.cell_overrides(wf, "meas", "akf", cell)[-1] == "method.options.measurement=acceleration"
    with pytest.raises(GridError, match="runs on none of its cells"):
        targets.identify_jobs(wf, "meas", "fft")


@pytest.mark.parametrize(("change", "message"), [
    (("[10, 1000]", "[.nan]"), "noise_ug.0: not a finite number"),
    (("[10, 1000]", "[10, .inf]"), "noise_ug.1: not a finite number"),
    (("[10, 1000]", "[-1]"), "noise_ug.0: -1 is less than or equal to the minimum of 0"),
    (("n_samples: [64]\nreplicates: 2", "n_samples: [2048]\nreplicates: 1000000"),
     "cell noise10ug_n2048: replicates × n_samples = 1000000 × 2048 needs 15.3 GiB"),
    (("[fft, akf]", "[fft, nosuch]"), "unknown method 'nosuch'"),
    (("name: bad", "name: other"), "name: 'other' must match the file name 'bad'"),
    (("seed: 5", "seed: 5\nmethod_overrides: {akf: [method.options.nosuch=1]}"), "method.options.nosuch"),
    (("seed: 5", "seed: 5\nmethod_overrides: {akf: [method.options.rd=-1]}"), "rd"),
    (("seed: 5", "seed: 5\nmethods_overrides: {}"), "Additional properties are not allowed"),
    (("seed: 5", "seed: 5\nmethod_overrides: {pem: [method.options.n_starts=2]}"), "method_overrides.pem: not a "
                                                                                   "method of the grid"),
    (("[10, 1000]", "[10, 1.0e+308]"), "noise_ug = 1e+308 is above 1.02e+11 µg"),
    (("seed: 5", "seed: 5\nyardstick_prior: nosuch"), "yardstick_prior: 'nosuch': no configs/method/nosuch.yaml"),
    (("seed: 5", "seed: 5\nyardstick_prior: pem"), "yardstick_prior: 'pem' states no prior_rad_s and"),
    (("seed: 5", "seed: 36893488147419103232"), "seed = 36893488147419103232 must be an integer from 0"),
    (("seed: 5", "seed: 5\nmethod_overrides: {fft: ['prior=${oc.env:HOME}']}"),
     "method_overrides of fft: prior must be a list of frequencies"),
    (("seed: 5", "seed: 5\nmethod_overrides: {fft: ['prior=[3.5,19,23,500]']}"),
     "prior[3] = 500.0 rad/s is above the Nyquist frequency"),
])
def test_a_grid_a_job_would_refuse_is_refused_in_one_line(root, change, message):
    text = GRID.format(name="bad").replace(*change)
    wf = workflow_with(root, "bad", text)
    with pytest.raises(GridError) as info:
        wf.load_grid("bad")
    line = str(info.value)
    assert line.startswith("error: ") and "bad.yaml" in line and "\n" not in line
    assert message in line, line


def test_the_yardstick_prior_is_the_named_configs_prior_and_its_spread(root):
    import yaml

    wf = workflow_with(root, "bayes", GRID.format(name="bayes") + "yardstick_prior: pem_map\n")
    cfg = yaml.safe_load((root / "configs" / "method" / "pem_map.yaml").read_text())
    pem = yaml.safe_load((root / "configs" / "method" / "pem.yaml").read_text())
    mu, std = wf.yardstick_prior("pem_map")
    assert list(mu) == pem["prior_rad_s"] and list(std) == cfg["options"]["prior_std_rad_s"]
    assert targets.yardstick_args(wf, "bayes") == ("--prior-rad-s " + " ".join(f"{v:g}" for v in mu)
                                          + " --prior-std-rad-s " + " ".join(f"{v:g}" for v in std))
    assert targets.yardstick_files(wf, "bayes") == ["results/bayes/yardstick.csv"]
    assert targets.yardstick_cells(wf, "bayes") == [f"results/bayes/data/noise{u}ug_n64.npz" for u in (10, 1000)]
    assert targets.yardstick_files(workflow_with(root, "plain", GRID.format(name="plain")), "plain") == []


def test_an_option_a_method_refuses_is_named_before_any_job(root):
    """pem's own check_options refuses n_starts = -1 (the value a job would stop on, 76 lines later)."""
    wf = workflow_with(root, "starts", GRID.format(name="starts").replace("[fft, akf]", "[pem]")
                       + "method_overrides: {pem: [method.options.n_starts=-1]}\n")
    with pytest.raises(GridError, match=r"method_overrides of pem: .*n_starts"):
        wf.load_grid("starts")
    ok = workflow_with(root, "starts_ok", GRID.format(name="starts_ok").replace("[fft, akf]", "[pem]")
                       + "method_overrides: {pem: [method.options.n_starts=2]}\n")
    assert targets.identify_jobs(ok, "starts_ok", "pem")[0][-1] == "method.options.n_starts=2"
    assert '"n_starts":2' in resolved_config(ok.root, "pem", ("method.options.n_starts=2",))


def test_an_unknown_grid_is_refused_with_the_known_ones(root):
    wf = workflow_with(root, "plain", GRID.format(name="plain"))
    with pytest.raises(GridError, match="no such grid; known grids: .*plain"):
        wf.load_grid("nosuch")


@pytest.mark.parametrize(("targets", "expected"), [
    (["smoke", "--cores", "2"], ["smoke"]),
    (["-n", "results/paper/README.md", "results/smoke/tables"], ["paper", "smoke"]),
    (["results/mlflow.db", "report.html"], []),
])
def test_the_requested_grids_are_read_off_the_targets(targets, expected):
    assert requested_grids(targets, ["paper", "smoke"]) == expected


@pytest.mark.parametrize(("target", "message"), [
    ("results/nosuch/README.md", "no grid 'nosuch'"),
    ("results/../../etc/README.md", "may not climb out"),
    ("results/smoke/../../x", "may not climb out"),
])
def test_a_target_outside_the_grids_is_refused_in_one_line(target, message):
    with pytest.raises(GridError, match=message) as info:
        requested_grids([target], ["paper", "smoke"])
    assert str(info.value).startswith(f"error: {target}: ")


@pytest.mark.parametrize(("target", "message"), [
    ("results/plain/data/nosuch.npz", "not a dataset of grid plain; .* cells: noise10ug_n64, noise1000ug_n64"),
    ("results/plain/identify/nosuch", "no method 'nosuch' in grid plain; its methods: fft, akf"),
    ("results/plain/identify/fft/noise10ug_n64.csv", "ask for the folder results/plain/identify/fft"),
])
def test_a_target_inside_a_grid_names_its_cells_or_methods(root, target, message):
    wf = workflow_with(root, "plain", GRID.format(name="plain"))
    with pytest.raises(GridError, match=message) as info:
        check_target(wf, target)
    assert str(info.value).startswith(f"error: {target}: ")
    for fine in ("results/plain/data/noise10ug_n64.npz", "results/plain/identify/akf", "results/plain/README.md",
                 "smoke", "--cores"):
        check_target(wf, fine)


def test_a_bare_word_that_names_no_rule_is_found_and_option_values_are_not(tmp_path):
    argv = ["-n", "--cores", "2", "--executor", "slurm", "papr", "smoke", "results/smoke/README.md", "notes",
            "--forcerun", "identify"]
    words = command_line_targets(argv)
    assert words == ["papr", "smoke", "results/smoke/README.md", "notes"]     # "2", "slurm" are values
    (tmp_path / "notes").write_text("a file in the workflow's folder is a file target")
    assert unknown_rule_targets(words, {"paper", "smoke"}, tmp_path) == ["papr"]
    assert command_line_targets(["--no-such-option"]) == []          # Snakemake's own refusal, not ours


def test_an_old_rule_name_is_found_with_one_note_naming_the_new_one(capsys):
    """``track`` and ``tracking_mlflow`` (MLflow run logging) are ``runlog`` and ``tracking_runlog`` now."""
    argv = ["--cores", "2", "--forcerun", "track", "--until", "tracking_mlflow,identify", "--set-threads",
            "track=1", "tracking", "results/tracking/track/akf"]
    assert renamed_rules(argv) == ["track", "tracking_mlflow"]
    notes = capsys.readouterr().err.splitlines()
    assert notes == ["note: rule 'track' is now 'runlog'; the old name works until the next release",
                     "note: rule 'tracking_mlflow' is now 'tracking_runlog'; the old name works until the next "
                     "release"]
    assert renamed_rules(["--forcerun", "runlog", "tracking", "tracking_runlog"]) == []


def test_identify_priority_is_the_batch_s_known_cpu_time(tmp_path):
    # the last run's Snakemake benchmark first, then the cost model's per-cell fits (R x CPU per fit), else 0
    from experiments.workflow.resources import batch_cpu_s, identify_priority

    assert batch_cpu_s(tmp_path, "full", "bopdmd") is None and identify_priority(tmp_path, "full", "bopdmd") == 0
    model = tmp_path / "results" / "bench" / "sweep_cost" / "full.csv"
    model.parent.mkdir(parents=True)
    model.write_text("entry,noise_ug,n_samples,cpu_s_per_fit,replicates\nbopdmd,100,256,0.5,100\n"
                     "bopdmd,100,2048,1.25,100\nakf:tuned,100,256,0.01,100\n")
    assert batch_cpu_s(tmp_path, "full", "bopdmd") == pytest.approx(175.0)
    assert identify_priority(tmp_path, "full", "akf_tuned") == 1           # ceil(1.0)
    assert identify_priority(tmp_path, "full", "era") == 0                  # not in the model
    bench = tmp_path / "results" / "full" / "benchmarks" / "identify" / "bopdmd.tsv"
    bench.parent.mkdir(parents=True)
    bench.write_text("s\th:m:s\tmax_rss\tcpu_time\n61.2\t0:01:01\t120.5\t58.4\n")
    assert identify_priority(tmp_path, "full", "bopdmd") == 59
    bench.write_text("s\th:m:s\n61.2\t0:01:01\n")                           # no cpu_time column: wall
    assert identify_priority(tmp_path, "full", "bopdmd") == 62
    bench.write_text("garbage")
    assert identify_priority(tmp_path, "full", "bopdmd") == 175


def test_a_fresh_clone_orders_its_jobs_by_the_committed_costs(tmp_path):
    # no benchmark, no cost model: the committed table (experiments/workflow/job_cpu_s.csv) gives the priorities;
    # a measurement, when there is one, goes before it; write_defaults enters a grid's jobs and keeps the rest
    from experiments.workflow.resources import (
        DEFAULT_COSTS,
        batch_cpu_s,
        identify_priority,
        job_priority,
        measured_costs,
        write_defaults,
    )

    assert job_priority(tmp_path, "paper", "yardstick") == 0
    (tmp_path / DEFAULT_COSTS).parent.mkdir(parents=True)
    (tmp_path / DEFAULT_COSTS).write_text("grid,job,cpu_s\npaper,yardstick,120.8\npaper,identify/bopdmd,61.2\n"
                                          "full,identify/bopdmd,9000\npaper,paper/paper_fig3,nan\n")
    assert job_priority(tmp_path, "paper", "yardstick") == 121
    assert identify_priority(tmp_path, "paper", "bopdmd") == 62 and identify_priority(tmp_path, "paper", "era") == 0
    assert job_priority(tmp_path, "paper", "paper/paper_fig3") == 0                 # not a number: unknown
    bench = tmp_path / "results" / "paper" / "benchmarks" / "yardstick.tsv"
    bench.parent.mkdir(parents=True)
    bench.write_text("s\th:m:s\tcpu_time\n50.0\t0:00:50\t40.2\n")
    assert job_priority(tmp_path, "paper", "yardstick") == 41                    # the last run first
    model = tmp_path / "results" / "bench" / "sweep_cost" / "paper.csv"
    model.parent.mkdir(parents=True)
    model.write_text("entry,noise_ug,n_samples,cpu_s_per_fit,replicates\nera,100,256,0.01,20\n"
                     "era,100,128,0.02,20\nakf:tuned,100,256,0.001,20\n")
    assert batch_cpu_s(tmp_path, "paper", "era") == pytest.approx(0.6)
    costs = measured_costs(tmp_path, "paper")
    assert costs == pytest.approx({"identify/era": 0.6, "identify/akf_tuned": 0.02, "yardstick": 40.2})
    write_defaults(tmp_path, "paper", costs)
    rows = (tmp_path / DEFAULT_COSTS).read_text().splitlines()
    assert rows[0] == "grid,job,cpu_s" and "full,identify/bopdmd,9000" in rows
    assert "paper,yardstick,40.2" in rows and "paper,identify/bopdmd,61.2" in rows    # replaced; kept
    assert sum(r.startswith("paper,yardstick,") for r in rows) == 1


def test_a_job_s_priority_counts_the_steps_that_must_follow_it(tmp_path):
    # bottom-level list scheduling: an identify batch is followed by runlog_jobs (beside the aggregate) and runlog,
    # the yardstick and the paper experiments by the aggregate and runlog; unknown steps count 0
    from experiments.workflow.resources import DEFAULT_COSTS, downstream_cpu_s, identify_priority, job_priority

    (tmp_path / DEFAULT_COSTS).parent.mkdir(parents=True)
    (tmp_path / DEFAULT_COSTS).write_text("grid,job,cpu_s\npaper,identify/era,10\npaper,paper/paper_fig4,25\n"
                                          "paper,runlog_jobs,40\npaper,aggregate,20\npaper,runlog,5\n")
    assert downstream_cpu_s(tmp_path, "paper", "identify") == 45 and downstream_cpu_s(tmp_path, "full", "identify") == 0
    assert identify_priority(tmp_path, "paper", "era") == 55                 # 10 + max(40, 20) + 5
    assert job_priority(tmp_path, "paper", "paper/paper_fig4") == 50         # 25 + 20 + 5
    assert job_priority(tmp_path, "paper", "runlog_jobs") == 45              # 40 + 5
    assert identify_priority(tmp_path, "paper", "fft") == 0                  # its own cost unknown
    # the shorter batch first: the job runs that wait for it are the longer chain
    assert identify_priority(tmp_path, "paper", "era") > job_priority(tmp_path, "paper", "paper/paper_fig4")


def test_the_committed_costs_put_the_longest_jobs_first():
    # the shipped table (what a fresh clone orders its jobs by): the paper grid's yardstick and BOPDMD batch
    # ahead of pem's, and pem's ahead of the other batches; every job of the shipped paper and full grids costed
    from experiments.workflow.resources import default_cpu_s

    def cost(grid, job):
        return default_cpu_s(ROOT, grid, job)

    grids = Grids(ROOT)
    short = [cost("paper", f"identify/{e.replace(':', '_')}") for e in grids.load_grid("paper")["methods"]
             if e not in ("bopdmd", "pem")]
    longest = min(cost("paper", "yardstick"), cost("paper", "identify/bopdmd"))
    assert longest > cost("paper", "identify/pem") > max(short)
    for grid in ("paper", "full"):
        for entry in grids.load_grid(grid)["methods"]:
            assert cost(grid, f"identify/{entry.replace(':', '_')}") > 0, (grid, entry)
    for experiment in grids.load_grid("paper")["experiments"]:
        assert cost("paper", f"paper/{experiment}") > 0, experiment


def test_every_shipped_grid_passes_its_own_check():
    # what `snakemake results/<grid>/README.md` checks before it builds the DAG, for every grid file of the
    # repository: a grid that ships refused (a variant's per-loop option on a cell with another mode count) fails
    grids = Grids(ROOT)
    batch = [g for g in grids.grid_names() if g not in TRACKING_GRIDS]
    assert batch and TRACKING_GRIDS
    for name in batch:
        assert grids.cells(name), name
    for name in TRACKING_GRIDS:
        tracking_grid.cache_clear()
        assert tracking_grid(name)["tracker_list"], name
