"""What ``railsusp posterior train`` and ``join`` print of an estimator's checks: the table
of each parameter's widening and coverage on the held-out simulations, and one line per
number of sections fused.

Apart from :mod:`railsusp.cli.posterior`, the commands, and
:mod:`railsusp.cli.posterior_options`, the checks of their options: these read a trained
estimator's records and print, nothing more."""

from __future__ import annotations

from railsusp.cli.common import console, err_console, frame_table


def print_checks(checks, label: str = "", widened=lambda sections: False) -> None:
    """One line per checked number of sections: the coverage range, whether the draws
    checked were widened (``widened(sections)``) and the verdict."""
    for c in checks:
        cov = [p.coverage for p in c.checks]
        how = "widened" if widened(c.sections) else "no widening"
        console.print(
            f"{label}{c.sections} section(s): coverage {min(cov):.2f}-{max(cov):.2f} on "
            f"{c.checks[0].n} cases, {how}: " + ("passed" if c.passed else "FAILED")
        )


def print_calibration_table(est) -> None:
    """Per parameter: the widening fitted on the calibration cases and the coverage on the
    untouched test cases before and after it."""
    import pandas as pd

    from railsusp.store import read_json

    record = read_json(est.run / "posterior" / "calibration.json")
    before = {c["parameter"]: c["coverage"] for c in record["before"]}
    factors = (record.get("correction") or {}).get("factors", {})
    rows = [
        {
            "parameter": c.parameter,
            "widening": factors.get(c.parameter, 1.0),
            "coverage_before": before[c.parameter],
            "coverage_after": c.coverage,
            "coverage_p": c.coverage_p,
            "sbc_p": c.sbc_p,
            "passed": c.passed and c.parameter not in record.get("excessive_correction", []),
        }
        for c in est.calibration
    ]
    title = f"90 % intervals on {record['cases']} untouched held-out simulations"
    console.print(frame_table(pd.DataFrame(rows), title))
    for p in record.get("products", []):
        cov = [c["coverage"] for c in p["parameters"]]
        console.print(
            f"{p['sections']} sections fused: widening up to "
            f"{max(p['correction']['factors'].values()):.2f}, coverage after "
            f"{min(cov):.2f}-{max(cov):.2f} on {p['cases']} cases: "
            + ("passed" if p["passed"] else "FAILED")
        )


def print_verdict(est, folder, synthetic_checks=()) -> None:
    """The closing line of ``railsusp posterior train``: the estimator in ``folder`` passed,
    or a warning naming every check it failed: its one-section check (intervals too narrow,
    or widened beyond the bound) and each fused check of several sections (and of the
    synthetic likelihood's ``synthetic_checks``) that failed. A failed fused check was left
    out where the one-section check had been widened beyond the bound too."""
    excessive = est.correction.excessive if est.correction else []
    failed = [str(p.sections) for p in est.products if not p.passed]
    failed += [f"{c.sections} (synthetic likelihood)" for c in synthetic_checks if not c.passed]
    fused = (
        f"FAILED those of {', '.join(failed)} sections: a recording of as many sections is "
        "flagged NOT calibrated"
        if failed
        else ""
    )
    if est.calibrated and failed:  # "passed" after FAILED lines read as a contradiction
        err_console.print(
            f"warning: the estimator in {folder} passed its one-section coverage check, but "
            f"{fused}; train on more simulations"
        )
    elif est.calibrated:
        console.print(f"estimator in {folder}: coverage check passed")
    else:
        if excessive:
            one = (
                f"needed its intervals widened more than {est.correction.max_inflation:g} "
                f"times for {', '.join(excessive)}: flagged as not calibrated"
            )
        else:
            one = "FAILED its coverage check (intervals too narrow)"
        also = f", and {fused}" if failed else ""
        err_console.print(
            f"warning: the estimator in {folder} {one}{also}; train on more simulations"
        )
