"""Simulation campaigns: sample the suspension parameters, simulate every sample in every
condition, store force series and scalar features in a run directory.

Verbs (SALib style): :func:`make_design` samples (Latin hypercube from ``scipy.stats.qmc``,
optionally optimised, or a Saltelli/Sobol design from SALib for direct Sobol analysis);
:func:`run_campaign` evaluates batches of samples with the batched simulator, locally (all
cores, through the simulator's threads) or on a Dask cluster, and writes each finished batch
atomically; :func:`load_campaign` reads a run directory back.

Run directory::

    campaign.json                    configuration, its hash, provenance, layout
    design.parquet                   sample_id, the sampled parameters and the varied
                                     non-key parameters (SI)
    tracks.parquet                   per condition and sample: irregularity seed, FRA class,
                                     curve radius and cant (railsusp.variation)
    batches/<condition>/batch-NNNNN.features.parquet   tidy features of the batch
    batches/<condition>/batch-NNNNN.parquet            force series of the batch (float32)
    features.parquet                 all tidy features, written when the campaign completes
    nominal/batches/<condition>/...  optional: each sample's track run with every parameter
                                     nominal (railsusp.campaign.twins), same batch layout

A batch counts as done when its series file exists (it is written last, atomically and
fsynced, after its features file), so a campaign killed at any moment, or a power loss,
resumes with the same command, recomputing nothing already stored and never counting a
half-written batch as done. Results do not depend on where a batch ran: each sample is
integrated on its own. Samples whose simulation failed (derailment, divergence) keep their
rows with a non-zero ``status`` and NaN features; :func:`failed_runs` counts them.
"""

from railsusp.campaign.batch_simulation import features_table, simulate_task
from railsusp.campaign.design import (
    CHANNELS,
    STATISTICS,
    CampaignConfig,
    CampaignError,
    make_config,
    make_design,
    salib_problem,
    track_seeds,
    track_table,
)
from railsusp.campaign.results import (
    Campaign,
    failed_of,
    failed_runs,
    incomplete,
    load_campaign,
    require_complete,
)
from railsusp.campaign.run import run_campaign

__all__ = [
    "CHANNELS",
    "STATISTICS",
    "Campaign",
    "CampaignConfig",
    "CampaignError",
    "failed_of",
    "failed_runs",
    "features_table",
    "incomplete",
    "load_campaign",
    "make_config",
    "make_design",
    "require_complete",
    "run_campaign",
    "salib_problem",
    "simulate_task",
    "track_seeds",
    "track_table",
]
