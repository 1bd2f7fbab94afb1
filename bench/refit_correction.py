"""Fit the record correction of saved networks again under today's rule (the GP on at most
``MAX_RUNS`` training runs, railsusp.surrogate.correction), their weights untouched, on the
campaign they were trained on; prints each network's validation error before and after.

    python bench/refit_correction.py --run runs/tracks-8192-up \\
        runs/tracks-8192-up/surrogates/cnn-gru-seq-nominal-8k/uphill
"""

from __future__ import annotations

import sys
from pathlib import Path

import torch

from _cli import parser, positive_int, run_main
from railsusp.errors import RailsuspInputError
from railsusp.surrogate import load
from railsusp.surrogate.refit import refit_record_correction


def main(argv: list[str] | None = None) -> int:
    ap = parser(__doc__)
    ap.add_argument("bundles", type=Path, nargs="+", help="saved networks (RUN/surrogates/K/C)")
    ap.add_argument("--run", type=Path, required=True, help="the campaign they were trained on")
    ap.add_argument("--threads", type=positive_int, default=1)
    args = ap.parse_args(argv)
    torch.set_num_threads(args.threads)
    for bundle in args.bundles:
        try:
            old = load(bundle)
            new = refit_record_correction(bundle, args.run)
        except (OSError, RailsuspInputError, RuntimeError, ValueError) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 2
        for label, sur in (("before", old), ("after", new)):
            err = sur.meta.get("record_correction", {}).get("validation_error_corrected", {})
            runs = len(sur.correction.x_unit) if sur.correction is not None else 0
            print(
                f"{bundle} {label}: fitted on {runs} runs, validation error of the record "
                + ", ".join(f"{k} {100 * v:.3f} %" for k, v in err.items())
            )
    return 0


if __name__ == "__main__":
    run_main(main)
