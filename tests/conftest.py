import os

import pytest

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")


@pytest.fixture(autouse=True)
def user_data_dir(tmp_path, monkeypatch):
    """Each test's per-user data folder (resources.user_path) is its own temp dir, never the real one."""
    folder = tmp_path / "user-data"
    monkeypatch.setenv("DUALRGB_DATA_DIR", str(folder))
    return folder
