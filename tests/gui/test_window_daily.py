"""The window of a program people use all day (issue 25, items 6 and 8): an edited protocol
shows it is modified and saves as TOML that reads back to the same protocol; menus and
shortcuts for Run, Pause, Home, STOP and the tabs; a tooltip on every button."""

import math
import tomllib

import pyqtgraph as pg
from PySide6.QtWidgets import QPushButton

from gelrig.gui.tomlout import dumps
from gelrig.protocols.spec import paper_protocol, parse_protocol
from tests.gui.test_app import open_window, short_compression

__all__ = ["open_window"]


def test_paper_protocols_round_trip_through_the_toml_writer():
    for kind in ("compression", "shear"):
        table = tomllib.loads(paper_protocol(kind).read_text())
        assert tomllib.loads(dumps(table)) == table


def test_an_edited_protocol_is_marked_modified_and_saves_to_the_same_protocol(
        qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    source = tmp_path / "short.toml"
    source.write_text(dumps(short_compression()))
    window.protocol.load_file(source)
    panel = window.protocol
    assert not panel.modified and "*" not in window.windowTitle()
    assert "short.toml" in window.windowTitle()
    entry = panel.form.entry(1, "hold")
    entry.edit.setText("30 s")
    assert panel.modified and "(modified)" in panel.file_label.text()
    assert window.windowTitle().endswith("short.toml *")
    edited = panel.spec
    assert edited is not None
    target = tmp_path / "saved.toml"
    assert window._save_to(target) == target
    assert not panel.modified and not window.windowTitle().endswith("*")
    assert "saved.toml" in window.windowTitle()
    again = parse_protocol(tomllib.loads(target.read_text()), str(target))
    assert again == parse_protocol(panel.form.edited_table(), str(target))
    assert again.steps == edited.steps
    window.save_protocol()  # Save: to its file now
    assert tomllib.loads(target.read_text()) == panel.form.edited_table()


def test_menus_shortcuts_and_tooltips(qtbot, open_window):
    window = open_window(math.inf)
    shortcuts = {a.text().replace("&", ""): a.shortcut().toString()
                 for menu in window.menuBar().findChildren(type(window.menuBar().actions()[0]
                                                                .menu()))
                 for a in menu.actions()}
    assert shortcuts["Run the protocol"] == "Ctrl+R"
    assert shortcuts["Pause"] == "Ctrl+P"
    assert shortcuts["Home the stage"] == "Ctrl+H"
    assert "STOP all motion (Esc)" in shortcuts
    assert [a.shortcut().toString() for a in window.tab_actions] == [
        f"Ctrl+{i}" for i in range(1, 9)]
    window.tab_actions[2].trigger()
    assert window.left_tabs.currentIndex() == 2
    window.tab_actions[4].trigger()
    assert window.plot_tabs.currentIndex() == 1
    for panel in (window.manual, window.protocol, window.instruments, window.header,
                  window.banner):
        for button in panel.findChildren(QPushButton):
            assert button.toolTip(), (type(panel).__name__, button.text())


def test_size_splitters_and_recent_protocols_are_remembered(qtbot, open_window, tmp_path):
    window = open_window(math.inf)
    source = tmp_path / "short.toml"
    source.write_text(dumps(short_compression()))
    window._open_protocol(str(source))
    window.resize(700, 500)  # within the offscreen screen (800x600)
    window.main_split.setSizes([300, 400])
    qtbot.wait(50)
    sizes = window.main_split.sizes()
    window.close()
    again = open_window(math.inf)
    assert again.recent == [str(source.resolve())]
    assert [a.text() for a in again.recent_menu.actions()] == [str(source.resolve())]
    assert again.size().width() == 700 and again.size().height() == 500
    assert again.main_split.sizes() == sizes
    again.recent_menu.actions()[0].trigger()
    assert again.protocol.path == source.resolve()


def test_time_axes_stay_in_seconds_never_ks(qtbot, open_window):
    window = open_window(math.inf)
    plots = [w for w in window.findChildren(pg.PlotWidget)]
    assert plots
    times = 0
    for plot in plots:
        for side in ("bottom", "left"):
            axis = plot.getPlotItem().getAxis(side)
            if "time" in axis.labelText or axis.labelText.startswith("tau"):
                times += 1
                assert axis.labelText.endswith("(s)") and not axis.autoSIPrefix, \
                    axis.labelText
                assert not axis.labelUnits
    assert times >= 4


def test_results_read_with_their_unit_on_the_value_not_an_si_name():
    from gelrig.gui.runview import step_lines

    lines = step_lines({"measured_depth_m": 1.01711e-3, "held_s": 20.0, "passes_done": 3})
    assert "measured depth = 1.01711 mm" in lines
    assert "held = 20 s" in lines and "passes done = 3" in lines
