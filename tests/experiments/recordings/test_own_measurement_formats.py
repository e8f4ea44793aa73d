"""Done when: for each file format, a simulated impact test written with that format's own library goes
through the identify job with no prior, and the three cantilever modes come back within 2× their
Cramér–Rao bound, the damping within its reported 2σ, and the figure is written."""

from __future__ import annotations

import json

import numpy as np
import pytest

from experiments.simulate.impact import FS_HZ, simulate

# One record for every format (a format is a container: the same record must give the same answer in each),
# seed 1, the first of the physics tests' seeds, taken as it came. Each bound below is a 2σ check per mode.
SEED = 1


def write_csv(path, rec):
    import pandas as pd

    # a logger's CSV: time stamps rounded to 1 µs (the true step 1/2048 s = 0.00048828125 s is not printable)
    pd.DataFrame({"t": np.round(rec.t, 6), "tip accel [g]": rec.accel_g}).to_csv(path, index=False)
    return path, ["data.channel=tip accel"]


def write_uff(path, rec):
    import pyuff

    def channel(name, node, y):
        return pyuff.prepare_58(
            func_type=1, id1=name, id2="impact test", id3="", id4="", id5="", ver_num=0, load_case_id=0,
            rsp_ent_name="beam", rsp_node=node, rsp_dir=2, ref_ent_name="hammer", ref_node=0, ref_dir=0,
            ord_data_type=4, abscissa_spacing=1, abscissa_min=0.0, abscissa_inc=1.0 / FS_HZ, z_axis_value=0.0,
            abscissa_spec_data_type=17, abscissa_len_unit_exp=0, abscissa_force_unit_exp=0,
            abscissa_temp_unit_exp=0, abscissa_axis_units_lab="s",
            ordinate_spec_data_type=12, ordinate_len_unit_exp=1, ordinate_force_unit_exp=0,
            ordinate_temp_unit_exp=0, ordinate_axis_units_lab="g",
            orddenom_spec_data_type=0, orddenom_len_unit_exp=0, orddenom_force_unit_exp=0,
            orddenom_temp_unit_exp=0, orddenom_axis_units_lab="",
            z_axis_spec_data_type=0, z_axis_len_unit_exp=0, z_axis_force_unit_exp=0, z_axis_temp_unit_exp=0,
            z_axis_axis_units_lab="", x=rec.t, data=y, binary=0)
    uff = pyuff.UFF(str(path))
    uff.write_sets([channel("tip", 1, rec.accel_g), channel("root", 2, 0.1 * rec.accel_g)], mode="overwrite")
    return path, ["data.channel=tip"]


def write_lvm(path, rec):
    # lvm-read only reads: the file is written as LabVIEW's Write To Measurement File writes it (tab separated,
    # one header, X values printed to 6 decimals)
    head = ("LabVIEW Measurement\t\nWriter_Version\t2\nReader_Version\t2\nSeparator\tTab\nDecimal_Separator\t.\n"
            "Multi_Headings\tNo\nX_Columns\tOne\nTime_Pref\tRelative\n***End_of_Header***\t\n\t\n"
            f"Channels\t1\nSamples\t{rec.t.size}\nY_Unit_Label\tg\nX_Dimension\tTime\nX0\t0\n"
            f"Delta_X\t{1 / FS_HZ:.6f}\n***End_of_Header***\t\nX_Value\ttip\n")
    body = "".join(f"{t:.6f}\t{y:.7e}\n" for t, y in zip(rec.t, rec.accel_g, strict=True))
    path.write_text(head + body)
    return path, []


def write_tdms(path, rec):
    from nptdms import ChannelObject, TdmsWriter

    with TdmsWriter(str(path)) as w:
        w.write_segment([ChannelObject("accel", "tip", rec.accel_g,
                                       properties={"unit_string": "g", "wf_increment": 1.0 / FS_HZ,
                                                   "wf_start_offset": 0.0}),
                         ChannelObject("accel", "root", 0.1 * rec.accel_g,
                                       properties={"unit_string": "g", "wf_increment": 1.0 / FS_HZ})])
    return path, ["data.channel=accel/tip"]


def write_mat(path, rec):
    import scipy.io

    scipy.io.savemat(str(path), {"tip": rec.accel_g, "fs": FS_HZ, "units": "g"})
    return path, []


WRITERS = {"csv": write_csv, "uff": write_uff, "lvm": write_lvm, "tdms": write_tdms, "mat": write_mat}


def run_identify(overrides, run_dir):
    """The identify job as the command line runs it: composed, checked, run."""
    from hydra import compose, initialize_config_module

    from experiments.hydra_app.command_line import CONFIG_MODULE
    from experiments.hydra_app.config_store import register
    from experiments.jobs import identify

    register(with_methods=["pem"])
    with initialize_config_module(config_module=CONFIG_MODULE, version_base="1.3"):
        cfg = compose(config_name="identify", overrides=["method=pem", "runlog.enabled=false",
                                                         "progress=false", *overrides])
    identify.check(cfg)
    identify.run_job(cfg, run_dir, "pem")
    return json.loads((run_dir / "estimate.json").read_text())


@pytest.mark.parametrize("fmt", list(WRITERS))
def test_impact_record_modes_within_twice_the_crlb(fmt, tmp_path, capsys):
    rec = simulate(SEED)
    path, extra = WRITERS[fmt](tmp_path / f"beam.{fmt}", rec)
    out = run_identify([f"data.path={path}", *extra], tmp_path / "run")
    seg = out["segment"]
    assert seg["impulse_s"] == pytest.approx(rec.t_hit, abs=0.01)      # the blow was found
    assert seg["start_s"] > rec.t_hit                                  # and left out
    modes = out["modes"]
    assert len(modes) == 3, capsys.readouterr().out
    crlb = rec.crlb_rad_s(seg["start_s"], seg["stop_s"])
    w = np.array([m["freq_rad_s"] for m in modes])
    assert np.all(np.abs(w - rec.freq_rad_s) <= 2 * crlb), (w - rec.freq_rad_s) / crlb
    z, z_std = np.array([m["damping_ratio"] for m in modes]), np.array([m["damping_std"] for m in modes])
    assert np.all(np.abs(z - rec.damping) <= 2 * z_std), (z - rec.damping) / z_std
    assert all(m["determined"] for m in modes)
    assert np.array([m["amplitude_g"] for m in modes]) == pytest.approx(
        np.abs([0.6, 1.5, 1.0]) * np.exp(-rec.damping * rec.freq_rad_s * (seg["start_s"] - rec.t_hit)), rel=0.02)
    assert "stabilisation diagram" in out["how_found"]
    for name in ("measurement.png", "measurement.svg"):
        assert (tmp_path / "run" / name).stat().st_size > 10_000
