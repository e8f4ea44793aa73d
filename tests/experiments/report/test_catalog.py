"""Captions of a grid's outputs: every caption file is clean reStructuredText with a category and a title."""

import docutils.core
import pytest

from experiments.report import catalog

NAMES = sorted(p.stem for p in catalog.CAPTIONS.glob("*.rst") if not p.stem.startswith("_") and p.stem != "workflow")


@pytest.mark.parametrize("name", NAMES)
def test_caption_renders_without_rst_warnings_and_has_category_and_title(name):
    text = catalog.caption_of(name, {"longest": 256, "noise_ref": "1000", "grid": "smoke"})
    # halt on any warning: a stray |x| or *x is a substitution/emphasis error in the report
    docutils.core.publish_parts(text, writer="html", settings_overrides={"halt_level": 2,
                                                                              "report_level": 2})
    assert catalog.category_of(name) != "other" and catalog.title_of(name) != name
    assert "${" not in text


def test_placeholders_are_filled_and_unknown_outputs_land_in_other():
    assert "256 samples" in catalog.caption_of("rmse_vs_noise", {"longest": 256})
    assert catalog.category_of("no_such_figure") == "other"
    assert "no caption written yet" in catalog.caption_of("no_such_figure")
    assert catalog.sort_key("rmse_vs_noise") < catalog.sort_key("failure_map") < catalog.sort_key("coverage")
