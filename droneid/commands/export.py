"""``droneid export``: the final models of an identify result.json as Python, C, MATLAB or LaTeX."""
from __future__ import annotations

import json
import sys
from pathlib import Path

from ..errors import DataError
from ..io_util import atomic_write_text
from ..lazy import lazy_module
from ._common import options_text

_export = lazy_module("droneid.export")
_predict = lazy_module("droneid.predict")


def register(sub) -> None:
    p = sub.add_parser("export",
                       description="Write each target's final model (targets.<t>.final of an identify "
                                   "result.json: prior terms, effects and evolved terms expanded into one "
                                   "expression) as self-contained code; the header states the inputs, units, "
                                   "conventions and delays. See docs/use-the-model.md.")
    p.add_argument("result", metavar="RESULT.json", help="result.json of droneid identify")
    p.add_argument("--to", required=True, choices=("python", "c", "matlab", "latex"), help="output language")
    p.add_argument("-o", "--output", default=None, metavar="FILE",
                   help="write to FILE (atomically) instead of stdout; for matlab the file name "
                        "(without .m) is the function name")
    p.add_argument("--target", default=None, help="target(s), comma separated (default: every final model)")
    p.set_defaults(func=run)


def run(args) -> int:
    targets = [t.strip() for t in args.target.split(",")] if args.target else None
    models = _predict.load_models(args.result, targets)
    finals = [m["identified"] for t, m in models.items() if not t.startswith("_") and "identified" in m]
    if not finals:
        raise DataError(f"{args.result}: no final model to export (targets.<t>.final is written by "
                        f"droneid identify; older results hold only the engine model)")
    name = Path(args.output).stem if args.output and args.to == "matlab" else "droneid_model"
    provenance = json.loads(Path(args.result).read_text(encoding="utf-8")).get("provenance")
    # the reader options the model was identified with: a user's own CSV columns (--column),
    # MCAP topics, Motive body: what a reader of the header needs to feed the same signals
    read_with = options_text(models.get("_reader_options") or {})
    source = f"{args.result} (logs read with {read_with})" if read_with else str(args.result)
    text = _export.export_models(finals, args.to, source=source, name=name,
                         inputs=_export.input_sources(provenance))
    if args.output:
        atomic_write_text(args.output, text)
        print(f"wrote {args.output}", file=sys.stderr)
    else:
        sys.stdout.write(text)
    return 0
