"""A panel whose logic has not landed yet: shown disabled with one plain line saying so."""
from __future__ import annotations

from PySide6.QtCore import Qt
from PySide6.QtWidgets import QLabel, QVBoxLayout, QWidget


class NotAvailablePanel(QWidget):
    def __init__(self, title: str, what: str, parent: QWidget | None = None):
        super().__init__(parent)
        self.title = title
        label = QLabel(f"{title}: not available yet ({what}).")
        label.setAlignment(Qt.AlignmentFlag.AlignCenter)
        label.setWordWrap(True)
        lay = QVBoxLayout(self)
        lay.addWidget(label)
        self.setEnabled(False)
        self.message = label.text()
