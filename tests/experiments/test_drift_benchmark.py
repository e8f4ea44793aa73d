"""experiments/benchmarks/drift.py: its one-line refusals (a design seed is an option, a negative one is not)."""

import pytest

from experiments.benchmarks import drift


@pytest.mark.parametrize("argv, start", [(["--seed", "-1"], "error: --samples = 1024 must be at least 256, "
                                                            "--records = 20 at least 1 and --seed = -1"),
                                         (["--records", "0"], "error: --samples = 1024")])
def test_bad_values_are_one_error_line(argv, start, capsys):
    with pytest.raises(SystemExit) as exc:
        drift.main(argv)
    assert exc.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith(start) and err.count("\n") == 1
