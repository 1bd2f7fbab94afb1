"""What the simulation-based posterior is trained on (:class:`PosteriorSettings`): the
estimated parameters, conditions, section length, statistics families, training counts,
noise and seeds, each checked in one line naming the field and the accepted range when the
settings are made, before any simulation (docs/posterior.md)."""

from __future__ import annotations

from dataclasses import dataclass
from os import PathLike
from pathlib import Path
from typing import Any

from railsusp.conditions import WorkingCondition, make_condition
from railsusp.errors import RailsuspInputError, repeated_names
from railsusp.estimate.config import check_count, check_range
from railsusp.estimate.posterior_band_resolution import (
    BAND_RESOLUTION,
    BAND_RESOLUTION_RULE,  # noqa: F401 (of this module before its own)
    band_resolution_mark,
    check_resolution,
    check_stored_mark,
    mark_difference,
)
from railsusp.estimate.posterior_uniform_track import check_uniform_record
from railsusp.estimate.statistic_families import (
    needs_partner,
    needs_partner_q,
    parse_families,
    statistic_names,
)
from railsusp.numbers import is_whole
from railsusp.params import MAIN_SUSPENSION, spec

#: the largest ``condition_offset``: ten condition slots, and every seed below 2^31
#: (9 x :data:`~railsusp.estimate.posterior_data.OFFSET_SEED_BASE` + the largest kind's base
#: in :data:`~railsusp.estimate.posterior_data.SEED_BASE` and its span: change them together)
MAX_CONDITION_OFFSET = 9
#: the largest seed of the training and of the draws (numpy's and torch's generators)
MAX_SEED = 2**32 - 1
#: the combinations of statistics the synthetic likelihood reads by default
DEFAULT_PROJECTION_RANK = 15
#: accepted range (inclusive) of each count of :class:`PosteriorSettings`, whole numbers
#: only (one source with ``railsusp posterior train``'s options): a fraction passed the range
#: check and failed deep in the training (``ensemble`` 1.5: a TypeError after the
#: simulations) or was silently cut (``product_sections`` 2.7 checked 2).
#: ``n_calibration`` also takes 0 (no correction); ``n_product`` and ``product_cases`` are
#: per held-out set of several sections; ``statistics_emulator_cases`` (0, or 20 to
#: ``n_train``) is checked against ``n_train``
POSTERIOR_COUNTS: dict[str, tuple[int, int]] = {
    "n_train": (20, 1_000_000),
    "n_check": (10, 100_000),
    "n_calibration": (20, 100_000),
    "samples": (100, 100_000),
    "hidden_features": (1, 1000),
    "num_transforms": (1, 50),
    "seed": (0, MAX_SEED),  # numpy's generators take no negative seed
    "ensemble": (1, 20),
    "product_sections": (2, 1000),
    "n_product": (20, 100_000),
    "product_cases": (20, 100_000),
    "projection_rank": (1, 1000),
    "condition_offset": (0, MAX_CONDITION_OFFSET),
}


@dataclass(frozen=True)
class PosteriorSettings:
    """What the posterior estimator is trained on: ``parameters`` estimated (of X11-X20),
    the working ``conditions`` (each recorded in sections of ``section_s`` seconds),
    ``n_train`` training cases, ``n_calibration`` held-out cases that fit the spread
    correction (0: no correction) and ``n_check`` other held-out cases that test it, the
    instrument ``noise`` (fraction of channel RMS), ``sum_y`` (also the wheelset's lateral force
    ``sumY``, :func:`~railsusp.estimate.summaries.wheelset_force`: both wheels of the
    leading wheelset recorded), ``statistics``: the families of
    statistics (:mod:`railsusp.estimate.statistic_families`; the default, the EN 14363
    summary alone, is the estimator's before the families existed), ``projection_rank``: the
    number of their combinations the synthetic likelihood reads beyond that summary
    (:func:`~railsusp.estimate.posterior_synthetic_information.informative_projection`),
    ``statistics_emulator_cases``: 0, the synthetic likelihood's emulator of all the
    statistics is fitted on every training case and read through the projection; N > 0, it
    is fitted on the first N cases only (it chooses the projection and gives the gain
    model its levels) and a second emulator of the projected combinations alone is fitted
    on all ``n_train`` (:mod:`railsusp.estimate.posterior_emulator`), the network size, the
    number of flows in the ``ensemble`` and the ``seed`` of every draw.
    ``product_sections``: the numbers of sections at which the fused posterior of several
    sections is corrected and checked (none: an estimate of several sections is not
    calibrated), on ``n_product`` held-out cases of consecutive sections for the correction
    and ``n_product`` others for the check; ``product_cases`` (one count per entry of
    ``product_sections``, in the same order) gives each number of sections its own count
    instead, so that the longest records, the costliest to simulate, can be checked on fewer
    cases (see :meth:`product_sets`)."""

    conditions: tuple[WorkingCondition, ...]
    parameters: tuple[str, ...] = MAIN_SUSPENSION
    section_s: float = 20.0
    n_train: int = 2000
    n_check: int = 200
    noise: float = 0.03
    sum_y: bool = False
    samples: int = 1000
    hidden_features: int = 50
    num_transforms: int = 5
    seed: int = 0
    n_calibration: int = 200
    ensemble: int = 1
    product_sections: tuple[int, ...] = ()
    n_product: int = 100
    product_cases: tuple[int, ...] = ()
    statistics: tuple[str, ...] = ("en14363",)
    projection_rank: int = DEFAULT_PROJECTION_RANK
    statistics_emulator_cases: int = 0
    condition_offset: int = 0
    #: the wagon simulated (a WagonData, a packaged name such as "tare", or a wagon file);
    #: None, or the packaged loaded C80/K6 given by name, is stored as None (the settings
    #: and hash of estimators trained before the field existed)
    wagon: Any = None

    def __post_init__(self) -> None:
        if self.wagon is not None:
            from railsusp.vehicle.wagon import load_wagon

            try:
                wagon = load_wagon(self.wagon)
            except RailsuspInputError as exc:  # naming the field (the option: --wagon)
                said = str(exc)
                if said.startswith("wagon = "):
                    raise
                raise RailsuspInputError(f"wagon = {self.wagon}: {said}") from None
            object.__setattr__(self, "wagon", None if wagon == load_wagon() else wagon)
        dupes = repeated_names([c.name for c in self.conditions])
        if dupes:  # recordings are matched by name: one would fill every slot of its name
            raise RailsuspInputError(
                f"conditions: names repeat ({', '.join(dupes)}); accepted distinct conditions"
            )
        families = parse_families(self.statistics)
        if self.sum_y and "wheelset" in families:
            raise RailsuspInputError(
                "sum_y = true conflicts with the statistics family 'wheelset', which holds "
                "the wheelset sum of Y already; accepted one of the two"
            )
        object.__setattr__(self, "statistics", families)
        try:  # an unknown name: the same refusal as another parameter's, naming the field
            params = tuple(spec(p).symbol for p in self.parameters)
        except (RailsuspInputError, KeyError, TypeError, AttributeError):
            params = ()
        wrong = [p for p in params if p not in MAIN_SUSPENSION]
        if wrong or not params or len(set(params)) != len(params):
            raise RailsuspInputError(
                f"parameters {','.join(self.parameters) or '(none)'}: accepted a subset of "
                f"{','.join(MAIN_SUSPENSION)} without repeats"
            )
        object.__setattr__(self, "parameters", params)
        self._check_counts()
        _check_statistics_emulator(self.statistics_emulator_cases, self.n_train, families)
        _check_projection_rank(self.projection_rank, families)
        _check_lags(families, self.section_s)
        check_range("section_s =", self.section_s, 1.0, 600.0)
        check_range("noise =", self.noise, 0.0, 0.5)
        ks = tuple(sorted(int(k) for k in self.product_sections))
        order = sorted(range(len(ks)), key=lambda i: self.product_sections[i])
        counts = tuple(int(self.product_cases[i]) for i in order) if self.product_cases else ()
        object.__setattr__(self, "product_sections", ks)
        object.__setattr__(self, "product_cases", counts)
        if not self.conditions:
            raise RailsuspInputError("conditions: at least one working condition is needed")
        for c in self.conditions:
            check_resolution(c, self.section_s, families)
            check_drawn_tracks(c)
        conds = tuple(c.with_duration(self.section_s) for c in self.conditions)
        object.__setattr__(self, "conditions", conds)
        for c in conds:
            check_uniform_record(c, self.section_s * max(ks, default=1), self.wagon)

    def _check_counts(self) -> None:
        """A one-line error naming the field and its range (:data:`POSTERIOR_COUNTS`) unless
        every count is a whole number in it; each is then stored as a Python int."""
        for name in ("n_train", "n_check", "samples", "hidden_features", "num_transforms",
                     "seed", "ensemble", "projection_rank", "condition_offset"):  # fmt: skip
            check_count(f"{name} =", getattr(self, name), *POSTERIOR_COUNTS[name])
            object.__setattr__(self, name, int(getattr(self, name)))
        low, high = POSTERIOR_COUNTS["n_calibration"]
        n = self.n_calibration
        if not is_whole(n) or (n and not low <= n <= high):
            whole = "" if is_whole(n) else "an integer, "
            raise RailsuspInputError(
                f"n_calibration = {n}: accepted {whole}0 (no correction) or {low} to {high}"
            )
        low, high = POSTERIOR_COUNTS["product_sections"]
        ks = self.product_sections
        if any(not is_whole(k) or not low <= k <= high for k in ks) or len(set(ks)) != len(ks):
            raise RailsuspInputError(
                f"product_sections = {','.join(map(str, ks))}: accepted distinct section "
                f"counts from {low} to {high}, whole numbers"
            )
        low, high = POSTERIOR_COUNTS["product_cases"]
        counts = self.product_cases
        if counts and (
            len(counts) != len(ks) or any(not is_whole(c) or not low <= c <= high for c in counts)
        ):
            raise RailsuspInputError(
                f"product_cases = {','.join(map(str, counts))}: accepted one count from {low} "
                f"to {high} per entry of product_sections ({len(ks)}), whole numbers"
            )
        low, high = POSTERIOR_COUNTS["n_product"]
        if not is_whole(self.n_product) or (
            ks and not counts and not low <= self.n_product <= high
        ):  # the count of the held-out sets of several sections, where there are such
            whole = "" if is_whole(self.n_product) else "an integer "
            raise RailsuspInputError(
                f"n_product = {self.n_product}: accepted {whole}{low} to {high}"
            )
        if not is_whole(self.statistics_emulator_cases):
            raise RailsuspInputError(
                f"statistics_emulator_cases = {self.statistics_emulator_cases}: accepted an "
                f"integer, 0 or 20 to the training cases, n_train = {self.n_train}"
            )
        for name in ("n_calibration", "n_product", "statistics_emulator_cases"):
            object.__setattr__(self, name, int(getattr(self, name)))

    def to_dict(self) -> dict[str, Any]:
        d = {k: getattr(self, k) for k in self.__dataclass_fields__}
        d["conditions"] = [c.model_dump() for c in self.conditions]
        d["parameters"] = list(self.parameters)
        d["product_sections"] = list(self.product_sections)
        d["product_cases"] = list(self.product_cases)
        d["statistics"] = list(self.statistics)
        if not self.product_cases:  # the settings (and hash) of estimators trained before it
            del d["product_cases"]
        if self.statistics == ("en14363",):  # likewise; the summary is read as it is
            del d["statistics"], d["projection_rank"]
        if not self.statistics_emulator_cases:  # likewise: one emulator, of all statistics
            del d["statistics_emulator_cases"]
        if not self.condition_offset:  # likewise: the conditions alone
            del d["condition_offset"]
        if self.wagon is None:  # likewise: the packaged loaded C80/K6
            del d["wagon"]
        else:
            d["wagon"] = self.wagon.model_dump(mode="json")
        mark = band_resolution_mark(self.conditions, self.statistics)
        if mark:  # sections whose band RMS takes a longer segment than it did (statistics
            # changed): a folder of them trained before is refused by its hash, not mixed
            d[BAND_RESOLUTION] = mark  # (the estimators of other sections keep theirs)
        return d

    @classmethod
    def from_dict(cls, d: dict[str, Any]) -> PosteriorSettings:
        """The settings an estimator folder stored (:meth:`to_dict`); refused in one line
        where their band statistics were computed before the band RMS followed the band
        edges (stored without this railsusp's :data:`BAND_RESOLUTION`:
        :func:`~railsusp.estimate.posterior_band_resolution.check_stored_mark`)."""
        d = dict(d)
        stored_mark = d.pop(BAND_RESOLUTION, None)  # follows from the sections
        d["conditions"] = tuple(make_condition(c) for c in d["conditions"])
        d["parameters"] = tuple(d["parameters"])
        d["product_sections"] = tuple(d.get("product_sections", ()))
        d["product_cases"] = tuple(d.get("product_cases", ()))
        d["statistics"] = tuple(d.get("statistics", ("en14363",)))
        if d.get("wagon") is not None:
            from railsusp.vehicle.wagon import WagonData

            d["wagon"] = WagonData.model_validate(d["wagon"])
        settings = cls(**d)
        check_stored_mark(stored_mark, settings)
        return settings

    def product_sets(self) -> list[tuple[int, int, tuple[int, ...]]]:
        """The held-out sets of several sections, as (cases, sections simulated, numbers
        of sections checked on them): the numbers of sections with the same count of cases
        share one set, simulated for the longest of them and cut (the first k sections for
        k); with one ``n_product`` for all, a single set."""
        counts = self.product_cases or (self.n_product,) * len(self.product_sections)
        out = []
        for n in dict.fromkeys(counts):
            ks = tuple(k for k, c in zip(self.product_sections, counts, strict=True) if c == n)
            out.append((n, max(ks), ks))
        return out

    @property
    def summary_names(self) -> list[str]:
        """Names of the summary vector: conditions one after the other."""
        names = statistic_names(self.statistics, self.sum_y)
        return [f"{c.name}:{n}" for c in self.conditions for n in names]

    @property
    def partner(self) -> bool:
        """Whether the statistics read the partner wheel of the measured wheelset."""
        return needs_partner(self.statistics, self.sum_y)

    @property
    def partner_q(self) -> bool:
        """Whether they read the partner wheel's Q too."""
        return needs_partner_q(self.statistics)


def _check_lags(families: tuple[str, ...], section_s: float) -> None:
    """A one-line error where a section is too short for the lagged correlations of the
    ``coherence`` family: at a lag of L seconds a section of S seconds correlates S - L of
    them, none at S = L (the correlation was NaN in every case and sbi failed with a
    traceback: the command-line audit of stop 60). Asked: half a second of overlap at the
    longest lag (25 samples at 50 Hz)."""
    from railsusp.estimate.statistic_families import AUTO_LAGS_S, CROSS_LAGS_S

    if "coherence" not in families:
        return
    longest = max(abs(lag) for lag in (*AUTO_LAGS_S, *CROSS_LAGS_S))
    least = longest + 0.5
    if section_s < least:
        raise RailsuspInputError(
            f"section_s = {section_s:g}: the statistics family 'coherence' correlates over "
            f"lags up to {longest:g} s, which needs sections of at least {least:g} s; "
            f"accepted {least:g} to 600"
        )


def check_drawn_tracks(condition: WorkingCondition) -> None:
    """Refuse a condition that names a measured track geometry, in one line: the posterior
    is trained for unknown track, each case on a track realisation of its own (its own
    irregularity seed), and a measured geometry would hold every case on that one track, an
    estimator conditioned on it and applied to recordings of any track as if calibrated
    for them (its cache was also keyed by the file's name, so a file edited in place was
    not simulated again: stop 78's hunt)."""
    if condition.track_geometry is not None:
        raise RailsuspInputError(
            f"conditions: {condition.name!r} names the measured track geometry "
            f"{condition.track_geometry}; the posterior is trained on a new track realisation "
            "per case (unknown track), which one measured track cannot give; accepted "
            "conditions without track_geometry (the design track and irregularity class)"
        )


def check_seed(seed: Any, name: str = "seed =") -> int:
    """``seed`` as an int, or a one-line error naming it (``name``: the argument, or the
    command line's ``--seed``) and the accepted range (:data:`POSTERIOR_COUNTS`): numpy's
    generators take no negative seed (a ValueError of theirs), nor a fraction (a
    TypeError)."""
    check_count(name, seed, *POSTERIOR_COUNTS["seed"])
    return int(seed)


def check_run_folder(run: Any, name: str = "run") -> Path:
    """``run`` as a Path, or a one-line error naming the argument ``name`` and what is
    accepted where it is no path (None gave a TypeError of pathlib's)."""
    if isinstance(run, bool) or not isinstance(run, str | PathLike) or not str(run):
        raise RailsuspInputError(
            f"{name} = {run!r}: accepted the run directory of a trained estimator (a str or a path)"
        )
    return Path(run)


def settings_differences(old: Any, new: dict[str, Any]) -> list[str]:
    """The settings in which a stored :meth:`PosteriorSettings.to_dict` (``old``, as read
    from a file: anything) differs from ``new``, each as ``name = old, not new`` (or the
    name alone where a value is long: conditions, a wagon), for the one-line refusal of a
    run folder trained with other settings. A field that one of them leaves out is its
    default (:meth:`~PosteriorSettings.to_dict` leaves defaults out for the hashes of
    before)."""
    if not isinstance(old, dict):
        return []
    fields = PosteriorSettings.__dataclass_fields__
    defaults = {k: f.default for k, f in fields.items()}
    defaults["statistics"] = list(defaults["statistics"])
    defaults["product_cases"] = []
    out = []
    for name in [k for k in fields if k in old or k in new]:
        was, now = old.get(name, defaults.get(name)), new.get(name, defaults.get(name))
        if was == now:
            continue
        if name in ("conditions", "wagon"):
            out.append(f"{name} differ" if name == "conditions" else "wagon differs")
        else:
            out.append(f"{name} = {_shown(was)}, not {_shown(now)}")
    said = mark_difference(old, new)
    return [*out, said] if said else out


def _shown(value: Any) -> str:
    if isinstance(value, list | tuple):
        return ",".join(map(str, value)) or "(none)"
    return str(value)


def _check_projection_rank(rank: int, families: tuple[str, ...]) -> None:
    """A one-line error unless ``projection_rank`` is its default with the EN 14363 summary
    alone, which is read as it is (the rank was ignored, and left out of the hash)."""
    if rank != DEFAULT_PROJECTION_RANK and families == ("en14363",):
        raise RailsuspInputError(
            f"projection_rank = {rank} conflicts with statistics = en14363: the summary alone "
            f"is read as it is, without a projection; accepted {DEFAULT_PROJECTION_RANK} (the "
            "default), or statistics families beyond it"
        )


def _check_statistics_emulator(cases: int, n_train: int, families: tuple[str, ...]) -> None:
    """A one-line error unless ``statistics_emulator_cases`` is 0 or 20 to ``n_train``, and
    0 with the EN 14363 summary alone (read as it is: there is no projection to emulate)."""
    if cases and families == ("en14363",):
        raise RailsuspInputError(
            f"statistics_emulator_cases = {cases} conflicts with statistics = en14363: the "
            "summary alone is read as it is, without a projection; accepted 0, or statistics "
            "families beyond it"
        )
    if cases and not 20 <= cases <= n_train:
        raise RailsuspInputError(
            f"statistics_emulator_cases = {cases}: accepted 0 (one emulator of all "
            f"statistics) or 20 to the training cases, n_train = {n_train}"
        )
