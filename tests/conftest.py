import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

# the fault-injection suite: @pytest.mark.fault("<category>") and --reliability-table (tests/faults/plugin.py)
pytest_plugins = ["faults.plugin"]
