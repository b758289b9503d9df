"""The Results tab (issue 28, item 5): the runs of the runs folder listed from the catalog with
``gelrig runs``'s filters, a run killed by SIGKILL listed ``interrupted``, one opened in the
run view, two overlaid (two curves per panel, values side by side), and a damaged index
rebuilt with one warning line while the tab goes on listing."""

import math
import shutil

import pytest

from gelrig.cli import main
from gelrig.instrument.core.catalog import CATALOG_NAME
from tests.gelrig.test_cli_runs import TINY_LADDER, _killed, _short
from tests.gui import test_app

open_window = test_app.open_window  # the fixture: a window on a built-in simulated rig
SAMPLES = {"a1": ("gel-A1", "ada"), "b2": ("gel-B2", "bo"), "c3": ("gel-C3", "ada")}


@pytest.fixture(scope="module")
def lab(tmp_path_factory):
    """``runs/`` with three completed 2 s holds of three samples, and one run killed."""
    home = tmp_path_factory.mktemp("lab")
    root = home / "runs"
    short = _short(home, "2 s")
    for name, (sample, operator) in SAMPLES.items():
        assert main(["run", str(short), "--out", str(root / name), "--no-rehearse",
                     "--sample", sample, "--operator", operator, "--tag", "week48"]) == 0
    _killed(_short(home, "300 s"), root / "killed")
    return root


def browse(qtbot, window, root):
    """The Results tab on ``root``, brought forward (which lists the runs)."""
    window.results.root = root
    window.plot_tabs.setCurrentWidget(window.results_tab)
    assert window.results.refreshing  # read on a thread: the window goes on meanwhile
    qtbot.waitUntil(lambda: not window.results.refreshing, timeout=20_000)
    return window.results


def find(qtbot, browser):
    """Press Find and wait for the list."""
    browser.find_button.click()
    qtbot.waitUntil(lambda: not browser.refreshing, timeout=20_000)


def listed(browser):
    return {e["name"]: e for e in browser.entries}


def test_the_runs_are_listed_with_samples_and_statuses_and_filtered(qtbot, open_window, lab):
    window = open_window(math.inf)
    browser = browse(qtbot, window, lab)
    found = listed(browser)
    assert set(found) == {"a1", "b2", "c3", "killed"}
    assert browser.table.rowCount() == 4
    assert {n: found[n]["sample"] for n in SAMPLES} == {n: s for n, (s, _o) in SAMPLES.items()}
    assert {n: found[n]["status"] for n in found} == {
        "a1": "completed", "b2": "completed", "c3": "completed", "killed": "interrupted"}
    rows = {browser.table.item(r, 0).text(): r for r in range(4)}
    status = browser.table.item(rows["killed"], 5).text()
    assert status == "interrupted (run.json: running)"  # as gelrig runs shows it
    browser.filters["sample"].setText("gel-B2")
    find(qtbot, browser)
    assert [e["name"] for e in browser.entries] == ["b2"] and browser.table.rowCount() == 1
    browser.filters["sample"].setText("gel-A*, gel-C3")
    browser.filters["operator"].setText("ada")
    find(qtbot, browser)
    assert sorted(listed(browser)) == ["a1", "c3"]
    browser.filters["sample"].setText("")
    browser.filters["operator"].setText("")
    browser.filters["status"].setText("interrupted")
    find(qtbot, browser)
    assert sorted(listed(browser)) == ["killed"]
    browser.filters["since"].setText("last tuesday")  # a bad filter: its line, list kept
    browser.find_button.click()
    assert "since" in browser.status.text() and "7d" in browser.status.text()
    assert sorted(listed(browser)) == ["killed"]


def test_two_runs_overlay_as_two_curves_with_their_values_side_by_side(qtbot, open_window,
                                                                      lab):
    window = open_window(math.inf)
    browser = browse(qtbot, window, lab)
    browser.select(["a1"])
    assert browser.open_button.isEnabled() and not browser.compare_button.isEnabled()
    browser.select(["a1", "b2"])
    assert browser.compare_button.isEnabled() and not browser.open_button.isEnabled()
    browser.compare_button.click()
    qtbot.waitUntil(lambda: not browser.loading, timeout=20_000)
    view = browser.compare
    force_t, force_z = view.curves("force_t"), view.curves("force_z")
    assert len(force_t) == 2 and len(force_z) == 2
    assert [c.name() for c in force_t] == ["a1 (gel-A1)", "b2 (gel-B2)"]
    # one legend above the panels, in the curves' colours; none inside a plot, where it lay
    # over a run's curve
    assert [(c, label) for c, _s, label in view.legend_entries] == [
        (force_t[0].opts["pen"].color().name(), "a1 (gel-A1)"),
        (force_t[1].opts["pen"].color().name(), "b2 (gel-B2)")]
    assert "a1 (gel-A1)" in view.legend.text() and view.legend.isVisible()
    assert all(plot.getPlotItem().legend is None for plot in view.plots.values())
    for curve in force_t + force_z:
        x, y = curve.getOriginalDataset()
        assert x.size > 100 and y.max() > 1e-3  # a hold pressing on the sphere (N)
    assert not view.curves("f_h") and not view.plots["f_h"].isVisible()
    header = [view.table.horizontalHeaderItem(c).text() for c in range(3)]
    assert header == ["result", "a1", "b2"]
    rows = {view.table.item(r, 0).text(): [view.table.item(r, c).text() for c in (1, 2)]
            for r in range(view.table.rowCount())}
    assert rows["sample"] == ["gel-A1", "gel-B2"]
    depth = rows["ramp and hold/depth_m"]
    assert all(text.endswith(" mm") for text in depth)


def test_a_run_opens_in_the_run_view(qtbot, open_window, lab):
    window = open_window(math.inf)
    browser = browse(qtbot, window, lab)
    browser.select(["c3"])
    browser.open_button.click()
    assert len(window.run_windows) == 1
    assert window.run_windows[0].windowTitle() == "gelrig — run c3 (completed)"


def test_a_damaged_index_is_rebuilt_with_one_warning_and_the_tab_goes_on(
        qtbot, open_window, lab, tmp_path):
    root = tmp_path / "runs"
    # a run window of an earlier test may still be writing its analysis (a .part file that
    # is renamed when done): copy the runs, not a file in the middle of being written
    shutil.copytree(lab, root, ignore=shutil.ignore_patterns("*.part"))
    (root / CATALOG_NAME).write_bytes(b"this is not an SQLite database" * 100)
    window = open_window(math.inf)
    browser = browse(qtbot, window, root)
    assert sorted(listed(browser)) == ["a1", "b2", "c3", "killed"]
    assert len(browser.warnings) == 1 and "rebuilt" in browser.warnings[0]
    assert "rebuilt" in browser.status.text()
    logged = [line for line in window.log.toPlainText().splitlines() if "rebuilt" in line]
    assert len(logged) == 1
    find(qtbot, browser)  # rebuilt: no warning the second time
    assert browser.warnings == [] and browser.table.rowCount() == 4
    (root / CATALOG_NAME).unlink()  # deleted: built again, silently
    find(qtbot, browser)
    assert browser.warnings == [] and (root / CATALOG_NAME).is_file()


def test_two_shear_runs_overlay_f_h_and_f_v_per_pass(qtbot, open_window, tmp_path):
    protocol = tmp_path / "ladder.toml"
    protocol.write_text(TINY_LADDER)
    root = tmp_path / "runs"
    for name in ("bead-S1", "bead-S2"):
        assert main(["run", str(protocol), "--sample", name, "--out", str(root / name),
                     "--no-rehearse"]) == 0
    window = open_window(math.inf, "shear")
    browser = browse(qtbot, window, root)
    browser.select(["bead-S1", "bead-S2"])
    browser.compare_button.click()
    qtbot.waitUntil(lambda: not browser.loading, timeout=20_000)
    view = browser.compare
    assert len(view.curves("f_h")) == 2 and len(view.curves("f_v")) == 2
    assert not view.curves("force_t")
    for curve in view.curves("f_h"):
        _x, y = curve.getOriginalDataset()
        assert y.size >= 1 and (y > 0).all()
