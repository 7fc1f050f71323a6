"""A virtual lab the window started (`dualrgb lab serve` as its child: app.lab.process) and what the window may
know of it: its addresses (the sphere and the camera are opened by them, like a physical stand's), its sample
changer (it places targets, the open gate, the lens cap and the originals' stand-ins), and the geometry it lays
its targets with (app.lab.targets: the window's stand-in for placing a grid by hand until the patches are found in
the image).

    lab = RunningLab(LabOptions(mode="reflective", frame_size=(600, 400))).start()
    lab.addresses["sphere"], lab.addresses["camera"]     # open_sphere / open_camera take them
    lab.place("test"); lab.use_charts(charts); lab.stop()

``in_process=True`` serves the same instruments from this process instead (drivers.virtual.lab_server.LabServer on
its own threads; the window's tests read its emulator's record, :attr:`RunningLab.emulator`); everything else is
the same, down to the addresses.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import TYPE_CHECKING, Any

from dualrgb.app.lab.process import LabOptions, LabProcess
from dualrgb.app.lab.targets import chart_reader, lab_grids, lab_scene

if TYPE_CHECKING:
    from dualrgb.app.processing.patches import PatchGrid
    from dualrgb.drivers.sample_changer import SampleChanger
    from dualrgb.simulation.charts import Chart

log = logging.getLogger(__name__)

CHART_COMMAND = "CHART"                 # the lab's sample changer's own command (docs/sample-changer-protocol.md)


class RunningLab:
    """See the module docstring."""

    def __init__(self, options: LabOptions, in_process: bool = False):
        self.options = options
        self.process: LabProcess | None = None if in_process else LabProcess(options)
        self.server: Any = None                     # in_process: the LabServer
        self.addresses: dict[str, str] = {}
        self.changer: SampleChanger | None = None
        self.placed = ""
        self.charts: dict[str, Chart] = {}

    def start(self) -> RunningLab:
        from dualrgb.app.workflow.stand_devices import open_changer

        self.addresses = self.process.start() if self.process is not None else self._serve_here()
        try:
            self.changer = open_changer(self.addresses["stand"])
            self.place("open-gate")
        except BaseException:
            self._stop_lab()
            raise
        return self

    def _serve_here(self) -> dict[str, str]:
        from dualrgb.drivers.virtual.lab_server import LabServer, LabSettings

        o = self.options
        settings = LabSettings(mode=o.mode, frame_size=o.frame_size, seed=o.seed, world=o.world, bumps=o.bumps,
                               stand_in=o.stand_in)
        if o.watchdog_s:
            settings.watchdog_s = o.watchdog_s
        self.server = LabServer(settings, light_record=o.light_record, read_chart=chart_reader(o.mode))
        return dict(self.server.start())

    def _stop_lab(self) -> None:
        if self.process is not None:
            self.process.stop()
        elif self.server is not None:
            self.server.stop()
            self.server = None

    @property
    def emulator(self) -> Any:
        """The sphere emulator (in_process only: a child's is out of reach, as a physical sphere's firmware)."""
        if self.server is None:
            raise RuntimeError("the virtual lab runs in its own process: watch its sphere through its port")
        return self.server.lab.emulator

    def stop(self) -> None:
        """Close the changer and stop the lab (it exits once its sphere is dark)."""
        changer, self.changer = self.changer, None
        if changer is not None:
            changer.close()
        self._stop_lab()

    # ---- what it is ----
    @property
    def mode(self) -> str:
        return self.options.mode

    @property
    def width(self) -> int:
        return int(self.options.frame_size[0]) // 2 * 2

    @property
    def height(self) -> int:
        return int(self.options.frame_size[1]) // 2 * 2

    @property
    def port(self) -> str:
        """The sphere's address."""
        return self.addresses.get("sphere", "")

    @property
    def world(self) -> str:
        return str(self.options.world or "nominal")

    # ---- the stand ----
    def _changer(self) -> SampleChanger:
        if self.changer is None:
            raise RuntimeError("the virtual lab is not started")
        return self.changer

    def place(self, what: str, nd: bool = False, stand_in: str = "") -> str:
        """Have the lab's sample changer put ``what`` on the stand (an original shown as ``stand_in`` when given:
        it is loaded in the changer's magazine under the original's identifier first)."""
        changer = self._changer()
        if stand_in and what.startswith("original:"):
            changer.load(what.removeprefix("original:"), stand_in)
        changer.place(what, nd)
        self.placed = what + (" + ND" if nd else "")
        return self.placed

    def use_charts(self, charts: dict[str, Chart]) -> None:
        """Put the stand's own charts on the lab's stand (the packaged targets for a role not given)."""
        from dualrgb.drivers.sample_changer import encode

        changer = self._changer()
        for role in ("train", "test"):
            chart = charts.get(role)
            if chart is None and role not in self.charts:
                continue
            fields: list[Any] = [role, "-", "-", "-"]
            if chart is not None:
                layout = "{}x{}".format(*chart.layout)
                fields = [role, layout, encode(",".join(chart.leave_out)) or "-", encode(str(Path(chart.file.path)))]
            changer.request(CHART_COMMAND, *fields)
        self.charts = {k: v for k, v in charts.items() if k in ("train", "test")}

    # ---- the geometry it lays its targets with ----
    def scene_for(self, what: str, nd: bool = False) -> Any:
        """The scene of target ``what`` ('train' / 'test') as the lab lays it (patch boxes for HDR metering)."""
        return lab_scene(self.mode, what, (self.width, self.height), self.charts.get(what), nd)

    def grids(self, charts: dict[str, Chart] | None = None) -> dict[str, PatchGrid]:
        """The training and test targets' grids (stack coordinates) as the lab lays ``charts`` (default: its own)."""
        return lab_grids(self.mode, (self.width, self.height), self.charts if charts is None else charts)
