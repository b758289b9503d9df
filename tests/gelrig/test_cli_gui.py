"""``gelrig gui`` before Qt starts: a missing system library or display is one line naming
the Debian packages (exit 2), not Qt's plugin error."""

import ctypes.util
from pathlib import Path

from gelrig.cli import main
from gelrig.commands import gui as command


def present(_name):
    return "/lib/x86_64-linux-gnu/lib.so"


def test_every_library_present_or_another_platform_needs_nothing():
    assert command.missing_libraries({"DISPLAY": ":0"}, present, "linux") == []
    assert command.missing_libraries({"QT_QPA_PLATFORM": "offscreen"}, lambda _n: None,
                                     "linux") == []
    assert command.missing_libraries({}, lambda _n: None, "darwin") == []


def test_a_missing_library_names_its_debian_package():
    def find(name):
        return None if name in ("xcb-cursor", "xcb-keysyms") else present(name)

    missing = command.missing_libraries({"DISPLAY": ":0"}, find, "linux")
    assert missing == ["libxcb-cursor0", "libxcb-keysyms1"]
    missing = command.missing_libraries({"QT_QPA_PLATFORM": "xcb:foo", "DISPLAY": ":0"}, find,
                                        "linux")
    assert missing == ["libxcb-cursor0", "libxcb-keysyms1"]


def test_gelrig_gui_without_libxcb_cursor_exits_2_with_one_line(monkeypatch, capsys):
    monkeypatch.setattr(command.sys, "platform", "linux")
    monkeypatch.setenv("DISPLAY", ":99")
    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.setattr(ctypes.util, "find_library",
                        lambda name: None if name == "xcb-cursor" else present(name))
    monkeypatch.setattr("gelrig.gui.app.run_app", lambda services: 0)  # never a real window here
    assert main(["gui"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1
    assert "libxcb-cursor0" in err and "apt-get install" in err
    assert "Traceback" not in err


def test_gelrig_gui_without_a_display_says_so(monkeypatch, capsys):
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    monkeypatch.delenv("QT_QPA_PLATFORM", raising=False)
    monkeypatch.setattr(ctypes.util, "find_library", present)
    monkeypatch.setattr(command.sys, "platform", "linux")
    monkeypatch.setattr("gelrig.gui.app.run_app", lambda services: 0)
    assert main(["gui"]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "xvfb-run" in err


def test_a_missing_glib_names_libglib():
    missing = command.missing_libraries(
        {"DISPLAY": ":0"}, lambda name: None if name == "glib-2.0" else present(name), "linux")
    assert missing == ["libglib2.0-0"]
    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    for _library, package in command.XCB_LIBRARIES:  # the README lists every one
        assert package in readme, package
