"""The Qt application at the rig (PySide6 + pyqtgraph). Only this package imports Qt."""
