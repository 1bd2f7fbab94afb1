"""Measured wheel-rail force recordings.

- :mod:`~railsusp.measured.recording`: one recording of one working condition (the field
  format) and its writer;
- :mod:`~railsusp.measured.recording_reader`, :mod:`~railsusp.measured.sidecar`: one
  recording's table and its JSON sidecar, read and checked strictly
  (:mod:`~railsusp.measured.field_table`: the table put on time;
  :mod:`~railsusp.measured.track_columns`: its speed and track columns against its
  condition);
- :mod:`~railsusp.measured.table_file`: a CSV or Parquet table's header and cells, checked
  alike for a recording and a long run;
- :mod:`~railsusp.measured.reader`: the field folder (``index.json``) read as a whole;
- :mod:`~railsusp.measured.raw`, :mod:`~railsusp.measured.units`,
  :mod:`~railsusp.measured.channels`, :mod:`~railsusp.measured.run`: long runs as the
  measurement system wrote them (ASAM MDF4, CSV, Parquet) read through a channel map,
  checked as a whole by :mod:`~railsusp.measured.run_checks`, their speed taken from the
  distance channel where they have none (:mod:`~railsusp.measured.speed_from_distance`);
- :mod:`~railsusp.measured.checks`: the checks every recording passes;
  :mod:`~railsusp.measured.sampling`: the one rule for force channels with missing samples
  (their effective rate, the share interpolated);
- :mod:`~railsusp.measured.breaks`: where a long run breaks (dropouts, NaN gaps longer than
  those interpolated, jumps of the distance channel), no section spanning one;
- :mod:`~railsusp.measured.track_kinds`, :mod:`~railsusp.measured.pieces`,
  :mod:`~railsusp.measured.sections`: a run's track per sample, a stretch cut into pieces
  kept or left out with their reasons (worded by :mod:`~railsusp.measured.reasons`), and
  the run cut into sections of one condition each;
- :mod:`~railsusp.measured.synthetic`: synthetic recordings of hidden true parameters;
  :mod:`~railsusp.measured.truth`: their truth, read and told to belong to recordings.
"""

from railsusp.measured.checks import MAX_GAP_SAMPLES
from railsusp.measured.reader import conditions_from, read_field, read_index
from railsusp.measured.recording import (
    FORMAT,
    Recording,
    RecordingError,
    SimulationFailedError,
)
from railsusp.measured.recording_reader import read_recording
from railsusp.measured.sidecar import inside
from railsusp.measured.synthetic import (
    add_sensor_noise,
    bandwidth_filter,
    recording_from_simulation,
    simulated_forces,
    synthesise_field,
)
from railsusp.measured.truth import check_truth_of, read_truth

__all__ = [
    "FORMAT",
    "MAX_GAP_SAMPLES",
    "Recording",
    "RecordingError",
    "SimulationFailedError",
    "add_sensor_noise",
    "bandwidth_filter",
    "check_truth_of",
    "conditions_from",
    "inside",
    "read_field",
    "read_index",
    "read_recording",
    "read_truth",
    "recording_from_simulation",
    "simulated_forces",
    "synthesise_field",
]
