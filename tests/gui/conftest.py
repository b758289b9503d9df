"""Each GUI test remembers its window's settings in a file of its own (QSettings)."""

import pytest


@pytest.fixture(autouse=True)
def own_settings(tmp_path, monkeypatch):
    monkeypatch.setenv("GELRIG_SETTINGS", str(tmp_path / "gui-settings.ini"))
