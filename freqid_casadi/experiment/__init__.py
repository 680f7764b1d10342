"""From time-domain experiments to frequency-response data (layer L1, SPEC §7, thesis §2.4).

Estimators (each returns a frozen :class:`FrfEstimate` whose ``data`` is a
:class:`~freqid_casadi.core.data.FrequencyData` ready for the fitters):

- :func:`frf_from_periodic`: periodic (multisine) excitation, averaged over whole periods;
- :func:`frf_from_realisations`: several realisations of it (new random phases), averaged,
  the noise told from the nonlinear distortions;
- :func:`frf_stepped_sine`: one record per frequency;
- :func:`frf_from_records`: any excitation (chirp, random, impulse): Welch H1/H2 with the
  coherence and the variance at every frequency.

Files and data sets: :func:`load_records_csv` (``u,y`` CSV), :func:`load_records_table`
(a table whose header names its columns: input and output chosen by name), :func:`load_daisy`,
:func:`load_daq_records` (a DAQ export), :func:`load_records_mat` (MATLAB variables or
struct fields by name), :func:`lvm_segments` (the segments of a LabVIEW measurement file),
and the data sets shipped with the package:
:func:`robot_arm` (DaISy 96-009, B. De Moor et al., DaISy: Database for the Identification
of Systems) and :func:`actuator_records` (servo-hydraulic actuator chirp test).
"""

from ._common import FrfEstimate
from .periodic import _detect_period, excitation_gaps, frf_from_periodic, frf_stepped_sine
from .records import (ACTUATOR_FILE, ROBOT_ARM_FILE, SHARED_ENV, DaqRecords, LvmSegment,
                      _find_robot_arm, actuator_records, dataset_path, load_daisy,
                      load_daq_records, load_records_csv, load_records_mat,
                      load_records_table, lvm_segments, robot_arm)
from .realisations import frf_from_realisations
from .welch import ESTIMATORS, frf_from_records

__all__ = [
    "FrfEstimate",
    "frf_from_periodic",
    "frf_from_realisations",
    "frf_stepped_sine",
    "excitation_gaps",
    "frf_from_records",
    "ESTIMATORS",
    "load_records_csv",
    "load_records_table",
    "load_daisy",
    "load_daq_records",
    "load_records_mat",
    "lvm_segments",
    "LvmSegment",
    "DaqRecords",
    "robot_arm",
    "actuator_records",
    "dataset_path",
    "ROBOT_ARM_FILE",
    "ACTUATOR_FILE",
    "SHARED_ENV",
]
