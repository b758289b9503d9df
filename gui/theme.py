"""Light or dark, as the system says (``QStyleHints.colorScheme``, Qt >= 6.5) unless the View
menu's Appearance says otherwise: the widgets' palette and every plot's background, axes and
titles. A plot drawn later takes the same colours (pyqtgraph's configuration)."""

from __future__ import annotations

import pyqtgraph as pg
from PySide6.QtCore import Qt
from PySide6.QtGui import QColor, QGuiApplication, QPalette
from PySide6.QtWidgets import QApplication, QStyleFactory, QWidget

#: The View menu's choices: (key, menu text).
CHOICES = (("system", "Follow the system"), ("light", "Light"), ("dark", "Dark"))

#: What :func:`apply` last set on the application ("dark": bool; "style": once set).
_applied: dict[str, bool] = {}

#: (background, foreground) of the plots.
PLOT_COLOURS = {False: ("w", "k"), True: ("#1e1e1e", "#dddddd")}


def system_dark() -> bool:
    """Whether the system asks for a dark appearance (False when it does not say)."""
    hints = QGuiApplication.styleHints()
    return hints.colorScheme() == Qt.ColorScheme.Dark


def is_dark(choice: str, system: bool) -> bool:
    """The appearance of ``choice`` ("system", "light" or "dark") when the system is
    ``system`` (dark or not)."""
    if choice not in {key for key, _text in CHOICES}:
        raise ValueError(f"appearance {choice!r}: one of {', '.join(k for k, _ in CHOICES)}")
    return system if choice == "system" else choice == "dark"


def _dark_palette() -> QPalette:
    palette = QPalette()
    roles = {QPalette.ColorRole.Window: "#2b2b2b", QPalette.ColorRole.WindowText: "#e6e6e6",
             QPalette.ColorRole.Base: "#1e1e1e", QPalette.ColorRole.AlternateBase: "#2f2f2f",
             QPalette.ColorRole.Text: "#e6e6e6", QPalette.ColorRole.Button: "#353535",
             QPalette.ColorRole.ButtonText: "#e6e6e6", QPalette.ColorRole.ToolTipBase: "#353535",
             QPalette.ColorRole.ToolTipText: "#e6e6e6", QPalette.ColorRole.Highlight: "#2f65ca",
             QPalette.ColorRole.HighlightedText: "#ffffff", QPalette.ColorRole.Link: "#6ea8fe",
             QPalette.ColorRole.PlaceholderText: "#9a9a9a"}
    for role, colour in roles.items():
        palette.setColor(role, QColor(colour))
    palette.setColor(QPalette.ColorGroup.Disabled, QPalette.ColorRole.Text, QColor("#7a7a7a"))
    palette.setColor(QPalette.ColorGroup.Disabled, QPalette.ColorRole.ButtonText,
                     QColor("#7a7a7a"))
    palette.setColor(QPalette.ColorGroup.Disabled, QPalette.ColorRole.WindowText,
                     QColor("#7a7a7a"))
    return palette


def apply(dark: bool, root: QWidget | None = None) -> None:
    """Dark or light: the application's palette (Fusion's, which follows it everywhere),
    pyqtgraph's colours for plots made later, and every plot under ``root`` now."""
    app = QApplication.instance()
    background, foreground = PLOT_COLOURS[dark]
    pg.setConfigOptions(background=background, foreground=foreground)
    if isinstance(app, QApplication) and _applied.get("dark") is not dark:
        # the style is set once, never again: replacing an application's style while
        # windows live crashed PySide6 (the old style deleted under them)
        if app.style().name().lower() != "fusion" and "style" not in _applied:
            style = QStyleFactory.create("Fusion")
            if style is not None:
                app.setStyle(style)
        _applied["style"] = True
        app.setPalette(_dark_palette() if dark else app.style().standardPalette())
        _applied["dark"] = dark
    if root is None:
        return
    for plot in root.findChildren(pg.PlotWidget):
        plot.setBackground(background)
        item = plot.getPlotItem()
        for side in ("left", "bottom", "right", "top"):
            axis = item.getAxis(side)
            axis.setPen(foreground)
            axis.setTextPen(foreground)
        item.titleLabel.setText(item.titleLabel.text, color=foreground)
