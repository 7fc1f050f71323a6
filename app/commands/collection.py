"""``dualrgb collection``: the collections' metadata presets (app.workflow.day.collection_presets) without writing
JSON - the same functions as the window's *Edit preset…*.

    dualrgb collection list [--collections DIR]
    dualrgb collection show NAME [--collections DIR] [--json PATH]
    dualrgb collection set NAME [--creator NAME ...] [--rights TEXT] [--credit TEXT] [--source TEXT]
                                [--extra FIELD=VALUE ...] [--template T] [--replace] [--collections DIR]

``set`` changes the fields it is given and keeps the others (``--replace``: starts from an empty preset, which is
also how a preset file that cannot be read is replaced); ``--creator`` given once or more is the whole creator
list; ``--extra FIELD=VALUE`` sets one extra field (``FIELD=``, an empty value: removes it); an empty text
(``--rights ""``) clears a field. Every value is checked as a preset file is read before anything is written: a bad
one is one line naming the option and the problem, and the file is left as it was.
"""
from __future__ import annotations

import argparse
import logging
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.commands.options import field_value
from dualrgb.app.json_output import add_json_option, text_stream, write_json

if TYPE_CHECKING:
    from dualrgb.app.workflow.day.collection_presets import CollectionPreset

log = logging.getLogger(__name__)

OPTION = {"creator": "--creator", "rights": "--rights", "credit": "--credit", "source": "--source",
          "extra": "--extra", "identifier_template": "--template", "name": "NAME"}    # a preset's field: its option


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("collection", help="list, show and set the collections' metadata presets")
    verbs = p.add_subparsers(dest="verb", metavar="VERB")
    verbs.required = True
    folder_help = "the collection presets' folder (default: presets/collections in the per-user data folder)"
    listing = verbs.add_parser("list", help="the collections with a preset, and what each sets")
    show = verbs.add_parser("show", help="what a collection's preset sets, field by field")
    show.add_argument("name", metavar="NAME", help="the collection (matched ignoring case)")
    add_json_option(show, "write the preset as JSON (a dualrgb-collection/1 preset file) to PATH ('-': standard "
                          "output)")
    put = verbs.add_parser("set", help="make or change a collection's preset (the fields given; the others kept)")
    put.add_argument("name", metavar="NAME", help="the collection; its preset file is named after it")
    put.add_argument("--creator", action="append", metavar="NAME",
                     help="a creator (XMP dc:creator); give it once per name: the whole list")
    for opt, what in (("--rights", "the rights statement (XMP dc:rights, TIFF Copyright)"),
                      ("--credit", "the credit line (XMP photoshop:Credit)"),
                      ("--source", "the institution (XMP photoshop:Source)"),
                      ("--template", "the identifier template: {counter} (e.g. {counter:04}), {date}, {operator}, "
                                     "{collection}")):
        put.add_argument(opt, metavar="TEXT", help=f"{what}; \"\" clears it")
    put.add_argument("--extra", action="append", type=field_value, default=[], metavar="FIELD=VALUE",
                     help="a default extra field of each original (FIELD=: removes it); repeat for more")
    put.add_argument("--replace", action="store_true",
                     help="start from an empty preset: the fields not given are left out (replaces a bad file)")
    for parser, func in ((listing, list_main), (show, show_main), (put, set_main)):
        parser.add_argument("--collections", type=Path, default=None, metavar="DIR", help=folder_help)
        parser.set_defaults(func=func)


def list_main(args: argparse.Namespace) -> int:
    """One line per collection with a preset: what it sets, or why its file cannot be used (exit 1 then)."""
    from dualrgb.app.workflow.day.collection_presets import (
        PresetError,
        collection_names,
        default_folder,
        find_preset,
    )

    folder = args.collections if args.collections is not None else default_folder()
    names, bad = collection_names(folder), 0
    if not names:
        print(f"no collection presets in {folder}")
    for name in names:
        try:
            preset = find_preset(name, folder)
            print(preset.summary() if preset is not None else f"preset {name}: gone")
        except PresetError as exc:
            bad += 1
            print(f"preset {name}: not used: {exc}")
    return 1 if bad else 0


def describe(preset: CollectionPreset) -> list[str]:
    """The preset field by field, one line each (``show``)."""
    c = preset.credits
    lines = [f"collection  {preset.name}" + (f"  ({preset.path})" if preset.path else "")]
    lines += [f"creator     {name}" for name in c.creator]
    lines += [f"{k:<11} {getattr(c, k)}" for k in ("rights", "credit", "source") if getattr(c, k)]
    lines += [f"extra       {k} = {v}" for k, v in preset.extra.items()]
    lines += [f"template    {preset.identifier_template}"] if preset.identifier_template else []
    return lines if len(lines) > 1 else [*lines, "(sets nothing)"]


def show_main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.day.collection_presets import PRESET_FORMAT, find_preset, preset_path

    preset = find_preset(args.name, args.collections)
    if preset is None:
        raise ValueError(f"collection {args.name}: no preset file {preset_path(args.name, args.collections)}")
    out = text_stream(args.json)
    for line in describe(preset):
        print(line, file=out)
    write_json(args.json, PRESET_FORMAT, preset.to_dict())
    return 0


def _start(args: argparse.Namespace) -> CollectionPreset:
    """The preset ``set`` changes: the collection's as it is, or an empty one (``--replace``, or none yet)."""
    from dualrgb.app.workflow.day.collection_presets import CollectionPreset, PresetError, find_preset, preset_path

    try:
        current = None if args.replace else find_preset(args.name, args.collections)
    except PresetError as exc:                                       # the file as it is: say how to replace it
        raise PresetError(f"{exc} (--replace starts from an empty preset)", exc.field) from None
    if current is not None:
        return current
    return CollectionPreset(preset_path(args.name, args.collections).stem)      # an existing file's own name


def _given(args: argparse.Namespace, field: str) -> str:
    """How the option of ``field`` was given, for a refusal: ``--rights 'text'``."""
    value = {"identifier_template": args.template, "creator": args.creator}.get(field, getattr(args, field, None))
    if field == "extra" or value is None:
        return OPTION.get(field, field)
    return f"{OPTION[field]} {value!r}" if isinstance(value, str) else f"{OPTION[field]} {', '.join(value)!r}"


def set_main(args: argparse.Namespace) -> int:
    from dualrgb.app.workflow.day.collection_presets import PresetError, make_preset, save_preset

    old = _start(args)
    given, c = {k for k, _ in args.extra}, old.credits
    try:
        preset = make_preset(
            old.name, creator=c.creator if args.creator is None else args.creator,
            rights=c.rights if args.rights is None else args.rights,
            credit=c.credit if args.credit is None else args.credit,
            source=c.source if args.source is None else args.source,
            extra=[*((k, v) for k, v in old.extra.items() if k not in given), *args.extra],
            identifier_template=old.identifier_template if args.template is None else args.template)
    except PresetError as exc:                                       # a value given here: its option and the problem
        raise ValueError(f"{_given(args, exc.field)}: {exc}") from None
    path = save_preset(preset, args.collections)
    print(f"saved {path}")
    print(preset.summary())
    return 0
