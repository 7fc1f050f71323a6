"""``dualrgb study ...``: studies around the light-source search, each writing JSON, PNG charts and a Markdown
summary into an output folder (logic in simulation.studies; this module only parses arguments and prints).

  dualrgb study speed-accuracy [--out DIR] [--seeds N] [--budget tiny|small|default]
  dualrgb study stability      [--out DIR] [--seeds N] [--budget tiny|default] [--pixels N]
  dualrgb study objectives     [--out DIR] [--budget tiny|default] [--no-virtual-lab]
  dualrgb study parsimony      [--out DIR] [--mode both|reflective|transmissive] [--budget tiny|default]
                               [--tolerance DE] [--write-defaults [PATH]]
  dualrgb study hdr            [--out DIR] [--mode both|...] [--budget tiny|default] [--write-defaults [PATH]]
  dualrgb study spectral       [--out DIR] [--budget tiny|default] [--modes reflective,transmissive] [--step NM]
  dualrgb study unbinned       [--out DIR] [--scheduler local|serial|ADDRESS] [--tasks N] [--top N]
  dualrgb study thesis         [--out DIR] [--budget full|small] [--json PATH] [--doc PAGE]
  dualrgb study sweep          [--modes reflective,transmissive] [--camera-csv A.csv ...] [--methods ...]
                               [--seeds N] [--scheduler local|ADDRESS]
  dualrgb study stand          [--out DIR] [--world W[,W...]|all] [--compare W,...|all|none] [--seeds N]
                               [--frame-size WxH] [--doc PAGE] [--from-json STAND.json]
                               (app.lab.stand_study)

``--out`` defaults to ``studies/<study>`` in the per-user data folder (resources.user_path), where the GUI lists
the charts. ``--scheduler`` runs a study's tasks through Dask: ``local`` starts a LocalCluster of worker processes
(``--workers``, 2 by default), an address (``tcp://host:8786``) uses a running scheduler, ``serial`` (the
default except for ``unbinned``) runs them here. Results are the same either way; timings are not comparable.
"""
from __future__ import annotations

import argparse
import logging
import sys
from dataclasses import replace
from pathlib import Path

from dualrgb import resources
from dualrgb.app.commands import study_thesis
from dualrgb.app.commands.options import count, frame_size, input_file, number, positive, worlds
from dualrgb.app.terminal_progress import TerminalProgress
from dualrgb.simulation.choices import MODES

log = logging.getLogger(__name__)


_workers = count(1, 64)


def _out_option(p: argparse.ArgumentParser, name: str) -> None:
    p.add_argument("--out", type=Path, default=None,
                   help=f"output folder (default: studies/{name} in the per-user data folder, where the GUI "
                        "finds the charts)")


def _out(args: argparse.Namespace) -> Path:
    from dualrgb import resources
    return args.out if args.out is not None else resources.user_path("studies", args.study)


BOTH = "both"


def _common(p: argparse.ArgumentParser, name: str, scheduler_default: str = "serial", both: bool = False) -> None:
    _out_option(p, name)
    if both:               # the studies that choose defaults answer for each mode
        p.add_argument("--mode", choices=(*MODES, BOTH), default=BOTH, help="target mode, or both (default)")
    else:
        p.add_argument("--mode", choices=MODES, default="reflective")
    p.add_argument("--step", type=number(1.0, 50.0, unit=" nm"), default=None,
                   help="spectral step in nm (default: the mode's grid, resources/parsimony.json)")
    p.add_argument("--camera-csv", type=input_file, help="measured camera sensitivities (wavelength_nm,R,G,B)")
    p.add_argument("--leds-csv", type=input_file, help="measured LED spectra (wavelength_nm,LED1..LED10)")
    p.add_argument("--train-csv", type=input_file, help="measured training target spectra")
    p.add_argument("--test-csv", type=input_file, help="measured test target spectra")
    p.add_argument("--scheduler", default=scheduler_default,
                   help=f"'serial', 'local' (Dask LocalCluster) or a Dask scheduler address "
                        f"(default {scheduler_default})")
    p.add_argument("--workers", type=_workers, default=2, help="LocalCluster worker processes (default 2)")


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("study", help="studies: speed vs accuracy, stability, parsimony, HDR merge, spectral "
                                     "estimation, unbinned search",
                       description="Studies around the light-source search; each writes JSON, PNG charts and "
                                   "SUMMARY.md into --out.")
    ss = p.add_subparsers(dest="study", metavar="STUDY")
    ss.required = True
    _optimiser_studies(ss)
    _default_studies(ss)
    _spectral_study(ss)
    _distributed_studies(ss)
    study_thesis.register(ss, _out_option)          # the thesis' tables reproduced (its own module)
    _stand_study(ss)


def _stand_study(ss: argparse._SubParsersAction) -> None:
    """stand: the workflow's stand model against captures in virtual-lab worlds (app.lab.stand_study)."""
    q = ss.add_parser("stand", help="the stand model against calibration captures in virtual-lab worlds: the "
                                    "measurement workflow's predicted vs captured dE00 (3 seeds), models' R^2, lights "
                                    "re-optimised on them vs the nominal preset and the world's optimum")
    _out_option(q, "stand")
    q.add_argument("--mode", choices=MODES, default="reflective")
    q.add_argument("--world", type=worlds, default=("mismatched-d700",), metavar="W[,W...]|all",
                   help="the virtual-lab worlds: packaged names or world JSON files, comma-separated, or 'all' (every "
                        f"packaged world: {', '.join(resources.world_names())}); default mismatched-d700")
    q.add_argument("--compare", type=worlds, default=None, metavar="W[,W...]|all|none",
                   help="worlds where every other stand model is compared too, with lights re-optimised on each "
                        "(about 3x longer per world); default: the world when only one is studied, else none")
    q.add_argument("--seeds", type=positive, default=3, help="capture seeds per light set (default 3)")
    q.add_argument("--frame-size", type=frame_size, default=(600, 400), help="virtual lab frames WxH (600x400)")
    q.add_argument("--doc", metavar="PAGE",
                   help="write the workflow table into the docs page PAGE (docs/explanation/stand-model.md) between "
                        "<!-- stand:start --> and <!-- stand:end --> (film: stand-transmissive)")
    q.add_argument("--from-json", type=input_file, metavar="STAND.json",
                   help="make the tables, charts (and --doc) from a study's saved stand.json instead of running it")
    q.set_defaults(func=stand_main)


def stand_main(args: argparse.Namespace) -> int:
    from dualrgb.app.lab.stand_study import StandStudyConfig, stand_study
    from dualrgb.app.workflow.stand_study_report import (
        load_study,
        readme_section,
        section_of,
        summary_lines,
        workflow_table,
        write_outputs,
    )
    from dualrgb.simulation.studies.common import StudyOutput, to_jsonable, write_marked

    out = StudyOutput(_out(args))
    if args.from_json:
        doc, source = load_study(args.from_json), str(args.from_json)
    else:
        if not args.world:
            raise ValueError("--world none: expected at least one world to study")
        compare = args.compare if args.compare is not None else args.world if len(args.world) == 1 else ()
        cfg = StandStudyConfig(worlds=args.world, mode=args.mode, frame_size=args.frame_size,
                               seeds=tuple(range(args.seeds)), compare=compare)
        with _progress(args) as progress:
            result = stand_study(cfg, out.folder / "work", progress=progress)
        doc, source = to_jsonable(result.to_dict()), "stand.json"
    write_outputs(doc, out, source)
    if args.doc:
        write_marked(args.doc, readme_section(doc, source if args.from_json else str(out.folder / "stand.json")),
                     section_of(doc))
        print(f"wrote the workflow table into {args.doc}", file=sys.stderr)
    lines = workflow_table(doc)
    return _done(out, lines if args.from_json else summary_lines(doc)[2:])


def _spectral_study(ss: argparse._SubParsersAction) -> None:
    """spectral: estimation methods x lights chosen for colour or for spectra, both modes."""
    q = ss.add_parser("spectral", help="spectral estimation: methods x colour- / spectral-chosen lights (+ 3-channel), "
                                       "spectral RMSE against dE00 and time")
    _out_option(q, "spectral")
    q.add_argument("--modes", default="reflective,transmissive", help="target sets (reflective,transmissive)")
    q.add_argument("--step", type=number(1.0, 50.0, unit=" nm"), default=10.0, help="spectral step in nm (10)")
    q.add_argument("--budget", choices=("tiny", "default"), default="default",
                   help="tiny: a short search for the spectral-chosen lights (a quick check)")
    q.add_argument("--doc", metavar="PAGE",
                   help="write the tables into the docs page PAGE (docs/explanation/spectral.md) between "
                        "<!-- spectral:start --> and <!-- spectral:end -->")
    q.add_argument("--from-json", type=input_file, metavar="SPECTRAL.json",
                   help="with --doc: the tables from a study's saved spectral.json instead of running it")
    q.set_defaults(func=spectral_main)


def _optimiser_studies(ss: argparse._SubParsersAction) -> None:
    """speed-accuracy, stability, objectives: how the optimisers and their objectives compare."""
    q = ss.add_parser("speed-accuracy", help="best error against time and evaluations for every optimiser")
    _common(q, "speed-accuracy")
    q.add_argument("--seeds", type=positive, default=3, help="seeds per configuration (default 3)")
    q.add_argument("--budget", choices=("tiny", "small", "default"), default="default")
    q.add_argument("--light-sets", type=positive, help="only the first N binned light sets (default all 630)")
    q.set_defaults(func=speed_accuracy_main)

    q = ss.add_parser("stability", help="seed spread, LED clipping, dim LEDs, sensitivity, predicted vs captured")
    _common(q, "stability")
    q.add_argument("--seeds", type=positive, default=3, help="seeds per optimiser (default 3)")
    q.add_argument("--budget", choices=("tiny", "default"), default="default")
    q.add_argument("--pixels", type=positive, help="pixels averaged per patch and channel (default 64)")
    q.add_argument("--no-virtual-lab", action="store_true",
                   help="skip the captures through the virtual camera and the processing pipeline")
    q.set_defaults(func=stability_main)

    q = ss.add_parser("objectives", help="noise-free, expected-captured and robust optima: speed, accuracy, "
                                         "predicted vs captured, both modes")
    _common(q, "objectives")
    q.add_argument("--budget", choices=("tiny", "default"), default="default")
    q.add_argument("--no-virtual-lab", action="store_true",
                   help="check against the pixel-level capture simulation instead of the virtual lab")
    q.set_defaults(func=objectives_main)


def _default_studies(ss: argparse._SubParsersAction) -> None:
    """parsimony, hdr: the studies that choose the packaged defaults (resources/parsimony.json)."""
    q = ss.add_parser("parsimony", help="coarsest spectral grid, simplest model, fewest HDR exposures, per mode")
    _common(q, "parsimony", both=True)
    q.add_argument("--budget", choices=("tiny", "default"), default="default")
    q.add_argument("--tolerance", type=number(0.0, 10.0), default=0.05, help="allowed loss in mean dE00 (default 0.05)")
    q.add_argument("--write-defaults", nargs="?", const=True, metavar="PATH",
                   help="also write the chosen defaults to PATH (no PATH: parsimony.json in the per-user data "
                        "folder, which the app then reads instead of its packaged defaults)")
    q.set_defaults(func=parsimony_main)

    q = ss.add_parser("hdr", help="HDR merge estimators: bias against signal, dE00 on dark originals, per mode")
    _common(q, "hdr", both=True)
    q.add_argument("--budget", choices=("tiny", "default"), default="default")
    q.add_argument("--write-defaults", nargs="?", const=True, metavar="PATH",
                   help="also write the chosen estimator (hdr_merge) into the defaults at PATH (no PATH: "
                        "parsimony.json in the per-user data folder); the other defaults there are kept")
    q.set_defaults(func=hdr_main)


def _distributed_studies(ss: argparse._SubParsersAction) -> None:
    """unbinned, sweep: the large searches, split into tasks for Dask."""
    q = ss.add_parser("unbinned", help="full-intensity search over all ~523 k unbinned light-source pairs")
    _common(q, "unbinned", scheduler_default="local")
    q.add_argument("--tasks", type=positive, default=16, help="index ranges the search is split into (16)")
    q.add_argument("--top", type=positive, default=10, help="best pairs to report (10)")
    q.add_argument("--limit", type=positive, help="only the first N pairs (for a quick check)")
    q.set_defaults(func=unbinned_main)

    q = ss.add_parser("sweep", help="targets x cameras x optimisers x seeds, one task each (Dask-ready)")
    _out_option(q, "sweep")
    q.add_argument("--modes", default="reflective,transmissive", help="target sets (reflective,transmissive)")
    q.add_argument("--camera-csv", action="append", default=[], metavar="CSV", type=input_file,
                   help="a camera sensitivity CSV to include (repeat; the packaged camera is always included)")
    q.add_argument("--methods", default="exhaustive,pso,halving",
                   help="optimisers (exhaustive,pso,ga,halving,pyswarms,de,lbfgs)")
    q.add_argument("--budget", choices=("tiny", "small", "default"), default="small")
    q.add_argument("--seeds", type=positive, default=2)
    q.add_argument("--light-sets", type=positive, help="only the first N binned light sets")
    q.add_argument("--scheduler", default="local", help="'serial', 'local' or a Dask scheduler address (local)")
    q.add_argument("--workers", type=_workers, default=2, help="LocalCluster worker processes (default 2)")
    q.set_defaults(func=sweep_main)


def _specs(args: argparse.Namespace) -> list:
    """One setup spec per mode asked for (``--mode both``: reflective, then transmissive)."""
    modes = MODES if args.mode == BOTH else (args.mode,)
    return [_spec(args, m) for m in modes]


def _spec(args: argparse.Namespace, mode: str | None = None):
    """The study's setup: ``mode`` (default ``--mode``) on its default grid (simulation.defaults), ``--step``
    replacing the step, and any measured CSVs."""
    from dualrgb.simulation.defaults import default_grid
    from dualrgb.simulation.studies.common import SetupSpec

    mode = mode or (MODES[0] if args.mode == BOTH else args.mode)
    grid = default_grid(mode)
    step = grid.step if args.step is None else args.step
    if step <= 0:
        raise ValueError(f"--step {args.step}: expected a positive number of nm")
    for name in ("camera_csv", "leds_csv", "train_csv", "test_csv"):
        path = getattr(args, name)
        if path and not Path(path).is_file():
            raise FileNotFoundError(f"--{name.replace('_', '-')} {path}: no such file")
    return SetupSpec(mode, step, grid.start, grid.end, camera_csv=args.camera_csv, leds_csv=args.leds_csv,
                     train_csv=args.train_csv, test_csv=args.test_csv)


def _progress(args: argparse.Namespace) -> TerminalProgress:
    return TerminalProgress(f"study {args.study}")


def _done(out, headline: list[str]) -> int:
    for line in headline:
        print(line)
    print(f"wrote {len(out.files)} files to {out.folder} (see {out.folder / 'SUMMARY.md'})", file=sys.stderr)
    return 0


def speed_accuracy_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.distributed import open_runner
    from dualrgb.simulation.studies.speed_accuracy import speed_accuracy, write_outputs

    spec = _spec(args)
    out = StudyOutput(_out(args))
    with open_runner(args.scheduler, workers=args.workers) as runner, _progress(args) as progress:
        result = speed_accuracy(spec, seeds=args.seeds, budget=args.budget, light_sets=args.light_sets,
                                runner=runner, progress=progress)
    write_outputs(result, out)
    best = min(result.summary, key=lambda r: r["train"]["median"])
    return _done(out, [f"{r['label']:<28} {r['seconds']['median']:8.2f} s  train {r['train']['median']:.4f}  "
                       f"test {r['test']['median']:.4f}" for r in result.summary]
                 + [f"best median training error: {best['label']} ({best['train']['median']:.4f})"])


def stability_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.distributed import open_runner
    from dualrgb.simulation.studies.stability import StabilityConfig, stability, write_outputs

    spec = _spec(args)
    cfg = StabilityConfig.tiny() if args.budget == "tiny" else StabilityConfig()
    cfg = replace(cfg, seeds=args.seeds if args.budget != "tiny" else cfg.seeds)
    if args.pixels:
        cfg = replace(cfg, camera=replace(cfg.camera, pixels_per_patch=args.pixels))
    capture, capture_model = _lab_capture(args, cfg.lab_repeats)
    out = StudyOutput(_out(args))
    with open_runner(args.scheduler, workers=args.workers) as runner, _progress(args) as progress:
        result = stability(spec, cfg, runner=runner, progress=progress, capture=capture,
                           **({"capture_model": capture_model} if capture_model else {}))
    write_outputs(result, out)
    return _done(out, _worked_example(result.noise))


def _lab_capture(args: argparse.Namespace, repeats: int):
    """The virtual lab's capture chain and its model for the expected-captured objective (None, None without)."""
    if args.no_virtual_lab:
        return None, None
    from dualrgb.app.captured_accuracy import capture_model, captured_errors

    def capture(setup, W, exposures):
        return captured_errors(setup, W, exposures, repeats=repeats)

    return capture, capture_model


def _worked_example(noise) -> list[str]:
    return [f"{r['mode']} {r['objective']:<17} {r['method']:<10} {r['pair']}: predicted noise-free "
            f"{r['noise_free_train']:.3f}, expected {r['expected_train']:.3f}, captured {r['captured_train']:.3f}"
            for r in noise.rows]


def objectives_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.objectives import ObjectivesConfig, objectives_study, write_outputs

    cfg = ObjectivesConfig.tiny() if args.budget == "tiny" else ObjectivesConfig()
    capture, capture_model = _lab_capture(args, cfg.capture_repeats)
    out = StudyOutput(_out(args))
    with _progress(args) as progress:
        result = objectives_study(_spec(args), cfg, capture=capture, progress=progress,
                                  **({"capture_model": capture_model} if capture_model else {}))
    write_outputs(result, out)
    return _done(out, _worked_example(result))


def _defaults_target(args: argparse.Namespace) -> str | None:
    """Where ``--write-defaults`` writes (no PATH: parsimony.json in the per-user data folder)."""
    from dualrgb import resources
    if not args.write_defaults:
        return None
    return str(resources.user_path("parsimony.json")) if args.write_defaults is True else args.write_defaults


def parsimony_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.parsimony import ParsimonyConfig, parsimony
    from dualrgb.simulation.studies.parsimony_report import write_outputs

    cfg = ParsimonyConfig.tiny() if args.budget == "tiny" else ParsimonyConfig()
    cfg = replace(cfg, tolerance=args.tolerance)
    out = StudyOutput(_out(args))
    with _progress(args) as progress:
        results = [parsimony(spec, cfg, progress=progress) for spec in _specs(args)]
    target = _defaults_target(args)
    write_outputs(results, out, target)
    lines = []
    for r in results:
        d = r.defaults()
        lines.append(f"{r.mode}: spectral grid {d['spectral_start_nm']:g}-{d['spectral_end_nm']:g} nm / "
                     f"{d['spectral_step_nm']:g} nm (thesis grid acceptable: {d['thesis_grid_acceptable']}), "
                     f"model {d['characterisation_model']}, {d['hdr_exposures']} HDR exposure(s); {r.elapsed_s:.0f} s")
    return _done(out, lines + ([f"defaults written to {target}"] if target else []))


def hdr_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.hdr import HdrStudyConfig, hdr_study, pm, write_defaults, write_outputs

    cfg = HdrStudyConfig.tiny() if args.budget == "tiny" else HdrStudyConfig()
    out = StudyOutput(_out(args))
    with _progress(args) as progress:
        result = hdr_study(_specs(args), cfg, progress=progress)
    write_outputs(result, out)
    target = _defaults_target(args)
    if target:
        write_defaults(result, target)
    lines = [f"{m}: bias per decade " + ", ".join(f"{d} DN/s {pm(100 * v['mean'], 100 * v['se'], ' %')}"
                                                  for d, v in result.bias[m]["bias_per_decade"].items())
             for m in result.bias["methods"]]
    lines += [f"{mode}: chosen HDR merge {o['chosen']} (training CV score "
              + ", ".join(f"{k} {v:.4f}" for k, v in o["scores"].items()) + ")"
              for mode, o in result.originals.items()]
    return _done(out, lines + ([f"defaults written to {target}"] if target else []))


def _modes(text: str) -> tuple[str, ...]:
    modes = tuple(m.strip() for m in text.split(",") if m.strip())
    bad = [m for m in modes if m not in MODES]
    if bad or not modes:
        raise ValueError(f"--modes {text!r}: expected some of {', '.join(MODES)}")
    return modes


def spectral_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import SetupSpec, StudyOutput, to_jsonable, write_marked
    from dualrgb.simulation.studies.spectral import (
        SpectralStudyConfig,
        load_study,
        readme_section,
        spectral_study,
        write_outputs,
    )

    if args.from_json:
        if not args.doc:
            raise ValueError("--from-json: give --doc docs/explanation/spectral.md (the tables are written there)")
        write_marked(args.doc, readme_section(load_study(args.from_json), args.from_json), "spectral")
        print(f"wrote the tables into {args.doc}", file=sys.stderr)
        return 0
    cfg = SpectralStudyConfig.tiny() if args.budget == "tiny" else SpectralStudyConfig()
    cfg = replace(cfg, modes=_modes(args.modes))
    out = StudyOutput(_out(args))
    with _progress(args) as progress:
        result = spectral_study(SetupSpec(cfg.modes[0], args.step), cfg, progress=progress)
    write_outputs(result, out)
    if args.doc:
        doc = to_jsonable({"format": "dualrgb-study-spectral/1", **result.to_json()})
        write_marked(args.doc, readme_section(doc, out.folder / "spectral.json"), "spectral")
        print(f"wrote the tables into {args.doc}", file=sys.stderr)
    return _done(out, [f"{r['mode']:<12} {r['lights']:<15} {r['method']:<8} RMSE {r['rmse']:.4f} (seen "
                       f"{r['rmse_seen']:.4f}), GFC {r['gfc']:.4f}, dE00 D65 {r['de00']['D65']:.3f} A "
                       f"{r['de00']['A']:.3f} FL11 {r['de00']['FL11']:.3f}" for r in result.rows])


def unbinned_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.studies.common import StudyOutput
    from dualrgb.simulation.studies.distributed import open_runner
    from dualrgb.simulation.studies.unbinned import compare_binned, unbinned_search, write_outputs

    spec = _spec(args)
    out = StudyOutput(_out(args))
    with open_runner(args.scheduler, workers=args.workers) as runner:
        result = unbinned_search(spec, runner, tasks=args.tasks, top=max(args.top, 10), limit=args.limit,
                                 refine=args.top)
    result.binned_best = compare_binned(spec)
    write_outputs(result, out)
    lines = [f"{result.pairs} pairs in {result.seconds:.2f} s ({result.runner.get('runner')})"]
    for n, c in zip(result.numbers, result.candidates, strict=True):
        s1, s2 = (s.label() for s in c.sources)
        train, test = (f"{e.mean:.4f}" if e is not None else "-" for e in (c.train, c.test))
        lines.append(f"#{n:<7} {s1:<24} {s2:<34} train {train} test {test}")
    lines.append(f"binned best: {result.binned_best['source1']} + {result.binned_best['source2']} "
                 f"train {result.binned_best['train_de00_mean']:.4f}")
    return _done(out, lines)


def sweep_main(args: argparse.Namespace) -> int:
    from dualrgb.simulation.defaults import default_grid
    from dualrgb.simulation.studies.common import SetupSpec, StudyOutput
    from dualrgb.simulation.studies.distributed import open_runner
    from dualrgb.simulation.studies.optimisers import OPTIMISERS
    from dualrgb.simulation.studies.sweep import sweep, write_outputs

    modes = list(_modes(args.modes))
    methods = [m.strip() for m in args.methods.split(",") if m.strip()]
    bad = [m for m in methods if m not in OPTIMISERS]
    if bad or not methods:
        raise ValueError(f"--methods {args.methods!r}: unknown {', '.join(bad) or '(none)'}; expected some of "
                         f"{', '.join(OPTIMISERS)}")
    for path in args.camera_csv:
        if not Path(path).is_file():
            raise FileNotFoundError(f"--camera-csv {path}: no such file")
    grids = {mode: default_grid(mode) for mode in modes}              # each mode on its default grid
    specs = [SetupSpec(mode, grids[mode].step, grids[mode].start, grids[mode].end, camera_csv=cam)
             for mode in modes for cam in [None, *args.camera_csv]]
    out = StudyOutput(_out(args))
    with open_runner(args.scheduler, workers=args.workers) as runner:
        result = sweep(specs, methods, budget=args.budget, seeds=args.seeds, light_sets=args.light_sets,
                       runner=runner)
    write_outputs(result, out)
    return _done(out, [f"{r['setup']:<40} {r['label']:<28} train {r['train']['median']:.4f} "
                       f"test {r['test']['median']:.4f}" for r in result.table])
