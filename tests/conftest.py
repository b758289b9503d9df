"""Shared test setup: Qt offscreen for every test that touches the GUI."""

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")
