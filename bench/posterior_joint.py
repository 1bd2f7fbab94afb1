"""The joint posterior of synthetic-likelihood estimators of different working conditions
(railsusp.estimate.posterior_joint), measured as bench/posterior_synthetic.py measures one
estimator: coverage of the 90 % intervals on the parts' held-out records, the issue's
identification of the middle-80 % sets, and the Cramer-Rao bound at the sets (issue 20).

    python bench/posterior_joint.py --runs RUN_SC,RUN_U --joint JOINT --lengths 20,120,600 \\
        --long 100 --long-length 600 --sets 12 --set-length 600 --set-lengths 20,60,120,300,600

Each run is an estimator trained and checked by bench/posterior_synthetic.py on the same
parameter draws (the same seed and held-out counts), the second with ``--condition-offset``
past the first's conditions (its own tracks and noise). Nothing is simulated or fitted
here beyond what the runs hold (their caches must hold the held-out records and the sets):

1. the joint widening per checked length, fitted on the first k sections of the parts'
   ``--calibration-records`` calibration records, and the joint check of the widened draws
   on the held-out records (one section on ``--check`` cases, k sections on the first k of
   the ``--long`` records, every length of ``--lengths``), stored in
   ``JOINT/posterior/joint.json`` with the parts' stamps;
2. with ``--sets N``: the N middle-80 % sets (bench/posterior.py's draws, each part's
   cached ``identification`` records) scored and judged at every length of
   ``--set-lengths`` as there;
3. the Cramer-Rao bound at the sets' truths for ``--set-length``: the parts' Fisher
   informations added (the conditions are independent given the parameters), with and
   without the emulators' error.
Prints the tables and writes JSON.
"""

from __future__ import annotations

import time

from _cli import parser, run_main
from posterior import KEYS, identify_sets, middle_draws
from posterior_synthetic import checked_sets, coverage_table, cramer_rao_table, posterior_seconds
from railsusp.estimate import posterior_joint as joint
from railsusp.estimate import posterior_synthetic_run as synthetic
from railsusp.store import write_json


def main() -> None:
    ap = parser(__doc__)
    ap.add_argument("--runs", required=True, help="the estimators' run folders, comma-separated")
    ap.add_argument("--joint", required=True, help="folder of the joint check (joint.json)")
    ap.add_argument("--out", default="bench/results/posterior_joint.json")
    ap.add_argument("--lengths", default="20,120,600", help="record lengths checked, s")
    ap.add_argument("--check", type=int, default=200, help="one-section held-out cases")
    ap.add_argument("--long", type=int, default=100, help="held-out records of several sections")
    ap.add_argument("--long-length", type=float, default=600.0, help="their length, s")
    ap.add_argument(
        "--calibration-records",
        type=int,
        default=150,
        help="the parts' long-calibration records of --long-length the widening is fitted on "
        "(0: no widening)",
    )
    ap.add_argument("--sets", type=int, default=0, help="middle-80 %% sets identified (0: none)")
    ap.add_argument("--set-length", type=float, default=600.0, help="their record length, s")
    ap.add_argument("--set-lengths", default=None, help="lengths they are scored at, s")
    ap.add_argument("--keys", default=KEYS, help="key parameters of the verdict")
    a = ap.parse_args()
    runs = [r for r in a.runs.split(",") if r.strip()]
    if len(runs) < 2:
        ap.error(f"--runs {a.runs}: accepted two or more run folders, comma-separated")

    t0 = time.perf_counter()
    parts = [synthetic.load(r) for r in runs]
    s = parts[0].settings
    section = s.section_s
    longest = max(1, round(a.long_length / section))
    sets = checked_sets(a, section, longest)
    where = ("long-calibration", a.calibration_records, longest) if a.calibration_records else None
    post = joint.train(runs, a.joint, sets, calibration=where)
    names = list(s.parameters)
    conditions = [c.name for p in post.parts for c in p.settings.conditions]
    print(f"joint posterior of {', '.join(runs)}: conditions {', '.join(conditions)}; "
          f"checked in {time.perf_counter() - t0:.0f} s (a stored check is read)")  # fmt: skip
    rows = [c.to_dict() for c in post.checks]
    coverage_table(rows, names, section)
    widening = {k: dict(zip(names, c.factors, strict=True)) for k, c in post.corrections.items()}
    print("widening (logit coordinates, fitted on the calibration records), per parameter")
    for k, factors in sorted(widening.items()):
        print(f"{k * section:8g} " + " ".join(f"{factors[p]:5.2f}" for p in names))

    ident, verdicts, bound = None, [], None
    if a.sets:

        def cases(kind, n, k, draws):
            return joint.joint_cases(post.parts, runs, kind, n, k, draws=draws)

        x, ident, verdicts = identify_sets(post, a, names, cases)
        posterior_seconds(post, x)
        u = middle_draws(s, a.sets)
        k_set = max(1, round(a.set_length / section))
        likelihoods = [p.likelihood for p in post.parts]
        bound = cramer_rao_table(likelihoods, post.columns, u, k_set, section, names)
    out = {
        "date": time.strftime("%Y-%m-%d"),
        "method": "joint-synthetic-likelihood",
        "runs": runs,
        "conditions": conditions,
        "settings": [p.settings.to_dict() for p in post.parts],
        "checks": rows,
        "calibration_records": a.calibration_records,
        "widening": {str(k): v for k, v in widening.items()},
        "identification": ident,
        "identification_verdicts": verdicts,
        "cramer_rao_width_pct": bound,
        "seconds": time.perf_counter() - t0,
    }
    write_json(a.out, out)
    print(f"wrote {a.out}")


if __name__ == "__main__":
    run_main(main)
