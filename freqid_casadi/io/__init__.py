"""Every reader and writer of frequency-response data (layer 2).

:mod:`.loaders` holds the public readers (:func:`~.loaders.load` dispatches on the file's
suffix: text tables, ``.npz``, ``.mat``, UFF 58, Touchstone) and :func:`~.loaders.save_csv`.
The text primitives below are shared with the time-record readers of
:mod:`freqid_casadi.experiment` and the command line, which parse their own tables.
"""

from ._columns import parse_freq_unit
from ._mat import matrix_records, read_mat_arrays, record_axis
from ._readfile import parse_band, read_regular_file
from ._decode import decode_text
from ._table import NUMBER, parse_columns, shown_cell

__all__ = ["read_regular_file", "read_mat_arrays", "matrix_records", "record_axis",
           "parse_band", "NUMBER", "decode_text", "parse_columns", "parse_freq_unit",
           "shown_cell"]
