"""``droneid predict``: apply a saved model (identify's result.json) to other logs, report its error."""
from __future__ import annotations

from ._common import print_json
from .identify import read_logs


def register(sub) -> None:
    p = sub.add_parser("predict", help="apply a saved model to other logs and report its error",
                       description="Apply the models of an identify result.json (or a single model file "
                                   "with --target) to other logs and report the RMSE per target and log, "
                                   "next to the empirical model's.")
    p.add_argument("model", metavar="RESULT_OR_MODEL.json", help="result.json of droneid identify, or a model file")
    p.add_argument("logs", nargs="+", metavar="LOG", help="log(s) to predict")
    p.add_argument("--target", default=None, help="target(s), comma separated (default: every target in the file)")
    p.add_argument("--ts", type=float, default=None, help="sampling period (default: the one identified with)")
    p.add_argument("--method", default=None, help="differentiator (default: the one identified with)")
    p.add_argument("--json", action="store_true", help="print the errors as one JSON line")
    p.set_defaults(func=run)


def run(args) -> int:
    from ..predict import load_models, predict_flights
    from ..reporting import fmt
    from ..report_identify import _text_table
    targets = [t.strip() for t in args.target.split(",")] if args.target else None
    models = load_models(args.model, targets)
    flights = read_logs(args.logs)
    res = predict_flights(models, flights, ts=args.ts, method=args.method)
    if args.json:
        from ..io_util import to_jsonable
        print_json(to_jsonable(res))
        return 0
    for t, r in res["targets"].items():
        print(f"== {t}: {r['equation'] or '(model)'}")
        keys = [k for k in ("rmse_identified", "rmse_empirical", "rmse_empirical_refit")
                if k in next(iter(r["errors"].values()))]
        labels = {"rmse_identified": "e_d identified", "rmse_empirical": "e_d empirical",
                  "rmse_empirical_refit": "e_d empirical refit"}
        header = ["data", "samples"] + [labels[k] for k in keys]
        rows = [[name, str(e["n"])] + [fmt(e[k]) for k in keys] for name, e in r["errors"].items()]
        print(_text_table(header, rows))
        print("errors: RMSE in m/s²\n")
    return 0
