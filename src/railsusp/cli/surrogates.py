"""Surrogate commands: train, compare."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Annotated

import numpy as np
import typer
from rich.table import Table

from railsusp.cli.common import (
    app,
    console,
    err_console,
    fail,
    frame_table,
    given_options,
    hold_folders,
    show_progress,
)
from railsusp.errors import RailsuspInputError, repeated

#: the training settings -> the options of ``train`` and ``compare``, for error messages
TRAIN_OPTIONS = {
    "training epochs": "--epochs",
    "training batches_per_epoch": "--batches-per-epoch",
    "training batch_size": "--batch-size",
    "training fine_tune_epochs": "--fine-tune-epochs",
    "training seed": "--seed",
    "device": "--device",
    "conditions": "--conditions",
}


def _epoch_reporter(bar, task):
    """A training progress callback bound to one progress-bar task."""

    def report(epoch: int, train_loss: float, val_loss: float) -> None:
        bar.update(task, completed=epoch, loss=f"train {train_loss:.4f} val {val_loss:.4f}")

    return report


# The argument and options ``train`` and ``compare`` share (both train networks on one
# campaign with the same settings), declared once so their help and types stay alike.
#: the campaign run directory both train on
RunDir = Annotated[Path, typer.Argument(help="campaign run directory")]
#: ``--conditions``: a comma-separated list of the campaign's conditions
ConditionsOption = Annotated[str | None, typer.Option(help="default: all of the campaign")]
#: ``--epochs``
Epochs = Annotated[int, typer.Option(help="maximum epochs (early stopping)")]
#: ``--fine-tune-epochs``
FineTuneEpochs = Annotated[
    int,
    typer.Option(
        help="then at most this many epochs at a tenth of the learning rate, from the best "
        "state (resumes a finished training)"
    ),
]
#: ``--batches-per-epoch``
BatchesPerEpoch = Annotated[int, typer.Option(help="mini-batches per epoch")]
#: ``--batch-size``
BatchSize = Annotated[
    int,
    typer.Option(
        help="windows per mini-batch, for the window networks (cnn-gru-seq trains on 32 "
        "chunks of 400 steps)"
    ),
]
#: ``--device``
TrainDevice = Annotated[str, typer.Option(help="cpu, cuda or auto")]
#: ``--seed``
TrainSeed = Annotated[
    int, typer.Option(help="training seed (compare: also the RBF centres' and the GPs')")
]


def _train_config(epochs, batches_per_epoch, batch_size, device, seed, fine_tune_epochs=0):
    from railsusp.surrogate import TrainConfig

    return TrainConfig(
        epochs=epochs,
        fine_tune_epochs=fine_tune_epochs,
        batches_per_epoch=batches_per_epoch,
        batch_size=batch_size,
        device=device,
        seed=seed,
    )


#: the training options of ``train`` and ``compare`` the networks alone take
NETWORK_OPTIONS = ("epochs", "fine_tune_epochs", "batches_per_epoch", "batch_size", "device")


def _check_device(device: str) -> None:
    """Refuse, before any note or training, a device that is not there (as ``train`` does)."""
    from railsusp.surrogate.train import resolve_device

    try:
        resolve_device(device)
    except RailsuspInputError as exc:
        raise RailsuspInputError(f"--device {device}: {exc}") from None


def _conditions(camp, conditions: str | None) -> list[str]:
    """``--conditions`` (all of the campaign's when not given), each checked before any
    training."""
    from railsusp.surrogate import check_conditions

    names = None if conditions is None else [c.strip() for c in conditions.split(",")]
    return check_conditions(camp, names if names is None else [c for c in names if c])


def _note_replaced(folder: Path, settings: dict, window: int, record_correction: bool) -> None:
    """Say so where the training replaces a saved network of other settings (a rerun with
    the same settings resumes, and says nothing): nothing but the printed line tells the
    user that the network read before is gone."""
    from railsusp.surrogate import replaced_settings

    _say_replaced(folder, replaced_settings(folder, settings, window, record_correction))


def _say_replaced(folder: Path, changed: list[str]) -> None:
    """The line of :func:`_note_replaced` (``compare`` is told ``changed`` by the library)."""
    if changed:
        console.print(
            f"note: replacing the network in {folder}, trained with other settings "
            f"({', '.join(changed)})",
            highlight=False,
            soft_wrap=True,  # one line, whatever the terminal's width
        )


@app.command()
def train(
    run: RunDir,
    model: Annotated[
        str,
        typer.Option(
            help="cnn-gru, cnn-lstm, cnn-bilstm, bp, cnn-gru-seq (sequence CNN-GRU), or "
            "gp-stats (statistics GPs)"
        ),
    ] = "cnn-gru",
    conditions: ConditionsOption = None,
    epochs: Epochs = 40,
    fine_tune_epochs: FineTuneEpochs = 0,
    batches_per_epoch: BatchesPerEpoch = 200,
    batch_size: BatchSize = 512,
    window: Annotated[
        int | None,
        typer.Option(help="window length, steps (20); cnn-gru-seq: its washout (100)"),
    ] = None,
    device: TrainDevice = "cpu",
    seed: TrainSeed = 0,
    record_correction: Annotated[
        bool,
        typer.Option(
            help="fit a GP of the record mean's error on the training runs and correct the "
            "predicted series by it"
        ),
    ] = True,
) -> None:
    """Train a window surrogate per condition (RUN/surrogates/<model>/<condition>/); print its
    accuracy on the held-out test samples. Re-running resumes from the last checkpoint.
    ``--model gp-stats`` fits the statistics GPs (mean, RMS, p99, std of |Y| and Q) instead,
    on every sample (their accuracy: ``railsusp compare``)."""
    from railsusp.campaign import load_campaign, require_complete
    from railsusp.surrogate import (
        KINDS,
        check_window,
        key_parameters,
        train_surrogate,
        unexplained_parameters,
    )
    from railsusp.surrogate.data import load_series
    from railsusp.surrogate.evaluate import accuracy, predict_with_alone
    from railsusp.surrogate.models import SEQUENCE_KINDS, default_window

    try:
        if model not in (*KINDS, "gp-stats"):
            raise RailsuspInputError(f"--model {model!r}: accepted {', '.join(KINDS)}, gp-stats")
        if model == "gp-stats":  # it fits GPs on every sample: no training setting is used
            unused = given_options(*NETWORK_OPTIONS, "seed", "window", "record_correction")
            if unused:
                raise RailsuspInputError(
                    f"{', '.join(unused)}: accepted only with the network models "
                    f"({', '.join(KINDS)}); --model gp-stats fits the statistics GPs, which "
                    "take no training settings"
                )
        elif model in SEQUENCE_KINDS and given_options("batch_size"):
            raise RailsuspInputError(
                f"--batch-size: accepted only with the window networks; --model {model} "
                "trains on mini-batches of 32 chunks of 400 steps"
            )
        tcfg = _train_config(epochs, batches_per_epoch, batch_size, device, seed, fine_tune_epochs)
        if model != "gp-stats":  # before any note that a network is being replaced
            _check_device(device)
        if window is not None and not 2 <= window <= 10_000:
            raise RailsuspInputError(f"--window = {window}: accepted 2 .. 10000 steps")
        # the campaign for the training's duration: no campaign --force or analysis
        # replaces what the networks are trained on (or their key parameters) meanwhile
        hold_folders(writes=[("", run)])
        camp = require_complete(load_campaign(run))
        conds = _conditions(camp, conditions)
        steps = window if window is not None else default_window(model)
        if model != "gp-stats":  # every condition's records before the first is trained
            try:
                check_window(camp, conds, model, steps, tcfg)
            except RailsuspInputError as exc:
                typed = "" if window is not None else f" (the default of {model})"
                raise RailsuspInputError(
                    re.sub(r"^window = (\d+) steps", rf"--window \1 steps{typed}", str(exc))
                ) from None
        left_out = unexplained_parameters(run)
        if left_out:
            err_console.print(
                f"[yellow]warning: no sensitivity analysis in {run}, so the surrogate inputs are "
                f"the study's six ({', '.join(key_parameters(run))}); "
                f"{', '.join(left_out)} also vary in this campaign and will read as noise: run "
                f"`railsusp sensitivity {run}` first[/]"
            )
        if model == "gp-stats":
            from railsusp.surrogate.statistics import train_statistics_surrogate

            for cond in conds:
                with console.status(f"{cond}: statistics GPs"):
                    sg = train_statistics_surrogate(run, cond)
                console.print(
                    f"{cond}: GPs of {', '.join(sg.statistics)} of |Y| and Q on "
                    f"{sg.meta['n_train']} runs -> {run / 'surrogates' / 'gp-stats' / cond}"
                )
            return
    except (RailsuspInputError, ValueError) as exc:
        fail(str(exc), options=TRAIN_OPTIONS)
    table = Table(title=f"{model}: accuracy on held-out simulations", title_justify="left")
    for col in (
        "condition",
        "force",
        "simulated kN",
        "predicted kN",
        "rel. error of mean (per run)",
        "(pooled)",
        "network alone (per run)",
        "NRMSE",
        "R2",
        "test runs",
    ):
        table.add_column(col, justify="left" if col in ("condition", "force") else "right")
    held_out: list[str] = []  # per condition, for the closing line
    for cond in conds:
        from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn

        _note_replaced(run / "surrogates" / model / cond, tcfg.to_dict(), steps, record_correction)

        with Progress(
            TextColumn(f"{cond} {model}"),
            BarColumn(),
            MofNCompleteColumn(),
            TextColumn("{task.fields[loss]}"),
            console=err_console,
            disable=not show_progress(),
        ) as bar:
            task = bar.add_task("train", total=epochs + fine_tune_epochs, loss="")
            try:
                sur = train_surrogate(
                    run,
                    cond,
                    kind=model,
                    window=window,
                    train=tcfg,
                    progress=_epoch_reporter(bar, task),
                    record_correction=record_correction,
                )
                error = None
            except (RailsuspInputError, ValueError) as exc:
                error = re.sub(r"^window = ", "--window ", str(exc))  # the option typed
                bar.update(task, visible=False)  # the error is the last line, not the bar
        if error is not None:
            fail(error)
        data = load_series(camp, cond, sur.spec)
        test = data.subset(np.flatnonzero(np.isin(data.sample_ids, sur.meta["test_ids"])))
        held_out.append(_held_out_line(camp, cond, sur, test))
        pred, raw = predict_with_alone(sur, test)
        sim = test.targets.astype(float)
        alone = None if raw is None else accuracy(sim, raw, sur.spec.targets, sur.spec.window)
        for k, r in enumerate(accuracy(sim, pred, sur.spec.targets, sur.spec.window)):
            table.add_row(
                cond,
                r["target"],
                f"{r['simulated_mean_kN']:.2f}",
                f"{r['predicted_mean_kN']:.2f}",
                f"{100 * r['relative_error_of_mean']:.2f} %",
                f"{100 * r['relative_error_of_pooled_mean']:.2f} %",
                "(no correction)"
                if alone is None
                else f"{100 * alone[k]['relative_error_of_mean']:.2f} %",
                f"{r['nrmse']:.3f}",
                f"{r['r2']:.3f}",
                str(r["n_samples"]),
            )
    console.print(table)
    from railsusp.surrogate.split import split_path

    held = sur.meta.get("split", {})  # (one split for the whole campaign)
    console.print(
        f"test runs hold out {held.get('held_out', 'parameter sets')} (split "
        f"{split_path(run, held.get('seed', 0))}): {'; '.join(held_out)}",
        highlight=False,
    )
    console.print(f"saved under {run / 'surrogates' / model}")


def _held_out_line(camp, cond: str, sur, test) -> str:
    """One condition's test runs for the train command's closing line: how many, on how many
    distinct tracks, and how many of the split's test samples failed (e.g. derailed) and are
    not scored (the table's count was of those that ran, with no word of the others)."""
    from railsusp.surrogate.split import campaign_split, condition_tracks

    split = campaign_split(camp, int(sur.meta.get("split", {}).get("seed", 0)))
    tracks = condition_tracks(camp, cond, test.sample_ids)
    failed = int(np.setdiff1d(split.test, test.sample_ids).size)  # as compare counts them
    return f"{cond} {len(test.sample_ids)} on {tracks} distinct track(s)" + (
        f", {failed} failed (e.g. derailed) and not scored" if failed else ""
    )


@app.command()
def compare(
    run: RunDir,
    models: Annotated[
        str,
        typer.Option(
            help="models to compare, comma-separated (also cnn-gru-seq, the sequence "
            "network, left out by default: its training is long)"
        ),
    ] = ("cnn-gru,cnn-lstm,cnn-bilstm,bp,rbf,gp-stats"),
    conditions: ConditionsOption = None,
    epochs: Epochs = 40,
    fine_tune_epochs: FineTuneEpochs = 0,
    batches_per_epoch: BatchesPerEpoch = 200,
    batch_size: BatchSize = 512,
    device: TrainDevice = "cpu",
    seed: TrainSeed = 0,
) -> None:
    """Train the surrogates (--models) on the same split and print the study's Table 7
    layout. The networks train with the window (washout) and record correction that
    ``train`` gives by default; a network that ``train`` saved with other settings is
    replaced, and a line says so."""
    from railsusp.campaign import load_campaign, require_complete
    from railsusp.surrogate.compare import ALL_MODELS, table7
    from railsusp.surrogate.compare import compare as run_compare
    from railsusp.surrogate.models import KINDS, SEQUENCE_KINDS

    names = [m.strip() for m in models.split(",") if m.strip()]
    bad = [m for m in names if m not in ALL_MODELS]
    if bad or not names:
        fail(
            f"--models {', '.join(bad) or '(none)'}: accepted one or more of "
            f"{', '.join(ALL_MODELS)}"
        )
    twice = repeated(names)  # each trained and tabled once: a repeat was a repeated row
    if twice:
        fail(f"--models {models}: models repeat ({', '.join(twice)}); accepted each once")
    try:
        # options none of the models chosen reads (rbf and gp-stats train no network; the
        # sequence network draws chunks, not --batch-size windows)
        networks = [m for m in names if m in KINDS]
        unused = given_options(*NETWORK_OPTIONS) if not networks else []
        if unused:
            raise RailsuspInputError(
                f"{', '.join(unused)}: accepted only with a network among --models "
                f"({', '.join(names)} train none)"
            )
        if networks and all(m in SEQUENCE_KINDS for m in networks) and given_options("batch_size"):
            raise RailsuspInputError(
                f"--batch-size: accepted only with a window network among --models "
                f"({', '.join(networks)} trains on mini-batches of 32 chunks of 400 steps)"
            )
        tcfg = _train_config(epochs, batches_per_epoch, batch_size, device, seed, fine_tune_epochs)
        if networks:  # as train does: before any training (rbf was fitted first)
            _check_device(device)
        hold_folders(writes=[("", run)])  # as train: the campaign for the command's duration
        conds = _conditions(require_complete(load_campaign(run)), conditions)

        with err_console.status("training surrogates") as status:
            tab = run_compare(
                run,
                models=names,
                conditions=conds,
                train=tcfg,
                progress=lambda msg: status.update(f"training {msg}"),
                note_replaced=_say_replaced,
            )
    except (RailsuspInputError, ValueError) as exc:
        fail(str(exc), options={**TRAIN_OPTIONS, "models": "--models"})
    t7 = table7(tab)
    fit_cols = ["Q NRMSE", "Y NRMSE", "Q R2", "Y R2"]
    console.print(
        frame_table(
            t7.drop(columns=fit_cols),
            "Surrogates on held-out simulations (study Table 7 "
            "layout, mean force of the measured wheel; |Y| for lateral)",
            fmt="{:.3f}",
        )
    )
    console.print(frame_table(t7[["condition", "model", *fit_cols]], "Series fit", fmt="{:.3f}"))
    console.print(f"wrote {run / 'surrogates' / 'compare.csv'} and overlay figures")
