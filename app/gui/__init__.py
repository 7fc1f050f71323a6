"""The copy-stand GUI (PySide6 + pyqtgraph): the only Qt code of the project. Panels wire widgets to the
Qt-free packages (drivers, core.session, app.sequences, app.processing, simulation); every device call and
computation runs off the GUI thread (app.gui.workers)."""
