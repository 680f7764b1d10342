"""The column vocabulary of text tables, ``columns=`` and ``.mat`` variables (layer L1).

A column is named by a role (frequency, real, imaginary, magnitude, phase, complex, skip)
and a unit: :func:`recognise` reads one header cell or name, :func:`parse_columns` a user's
``columns=``, :func:`parse_freq_unit` a user's ``freq_unit``. Used by
:mod:`freqid_casadi.io._table` (the text parser) and :mod:`freqid_casadi.io.loaders`.
"""

import re
from dataclasses import dataclass, replace

from ..errors import DataError, OptionError

__all__ = ["Column", "recognise", "parse_columns", "parse_freq_unit", "COLUMN_HELP",
           "one_layout", "columns_option", "complete_channels", "sparameter_of",
           "sparameters", "with_parameter", "DERIVED", "ChannelChoice", "several_responses",
           "time_column", "time_records"]

#: A channel or trace number before a column's name: ``Channel 2 Phase (deg)``, ``Ch1 Re``
#: (``_CHANNEL``: the number and the name after it).
_CHANNEL_NO = re.compile(r"^\s*(?:channel|chan|ch|trace|tr)\s*(\d+)", re.IGNORECASE)
_CHANNEL = re.compile(_CHANNEL_NO.pattern + r"\s*[:\-]?\s+(\S.*)$", re.IGNORECASE)
#: A trace named by a word, not a number: ``Trace |Z| (Ohm)``, ``Trace th (*)`` (Digilent
#: WaveForms' impedance export).
_TRACE_WORD = re.compile(r"^\s*trace\s+(\S.*)$", re.IGNORECASE)
_UNIT_RE = re.compile(r"^(.*?)[\s_]*[\[(]\s*([^\])]*?)\s*[\])]\s*$")

_UNITS = {"": None, "hz": "hz", "rad/s": "rad/s", "rad_s": "rad/s", "rads": "rad/s",
          "rad/sample": "rad/sample",
          "rad/sec": "rad/s", "radians/s": "rad/s", "db": "db", "deg": "deg",
          "degree": "deg", "degrees": "deg", "°": "deg", "rad": "rad", "radian": "rad",
          "radians": "rad", "lin": "lin", "linear": "lin",
          # a response's part named as its unit: "Gain (Real)", "TR1: Gain (Imag)"
          "real": "re", "re": "re", "imag": "im", "imaginary": "im", "im": "im",
          "abs": "lin", "absolut": "lin", "absolute": "lin", "magnitude": "lin",
          "mag": "lin"}
_SUFFIXES = ("_rad_sample", "_rad_s", "_rads", "_hz", "_db", "_degrees", "_deg", "_radians", "_rad")
#: (``freqency``: as the SR785 acquisition scripts of gravitational-wave labs spell it;
#: German, Spanish, French and Italian exports: ``Frequenz (Hz)``, ``Frecuencia (Hz)``, ...)
_FREQ = {"omega": "rad/s", "w": "rad/s", "f": None, "freq": None, "frequency": None,
         "freqency": None, "hz": "hz", "frequenz": None, "frecuencia": None,
         "fréquence": None, "frequence": None, "frequenza": None}
#: Frequency units with an SI prefix, as field solvers and network analysers write them
#: (``Freq [GHz]``), and each prefix's factor (``m``: milli, ``M``: mega, as written).
_PREFIXED_HZ = {"khz", "mhz", "ghz", "thz"}
_HZ_PREFIX = {"k": 1e3, "m": 1e6, "g": 1e9, "t": 1e12}     # (but "mHz" as written: milli)
_RE = {"re", "real"}
_IM = {"im", "imag", "imaginary"}
#: (``spl``: a sound pressure level, ``SPL(dB)`` in Room EQ Wizard's exports; ``|z|``:
#: ``Trace |Z| (Ohm)`` in WaveForms' impedance export; German, Spanish and Italian words)
_MAG = {"mag", "magnitude", "abs", "amplitude", "amp", "gain", "modulus", "spl", "|z|",
        "|h|", "|y|", "|g|", "betrag", "verstärkung", "amplitud", "ganancia", "ampiezza",
        "guadagno"}
#: A magnitude in decibels named by its unit alone (``dB``, ``dBSPL`` as ARTA writes it).
_DB = {"db", "dbspl", "db_spl", "dbv", "dbu", "dbr"}
#: (``th``/``θ``: the angle of an impedance, ``Trace th (*)`` in WaveForms' export;
#: ``fase``: Spanish, Italian)
_PHASE = {"phase", "phi", "arg", "angle", "ph", "th", "theta", "θ", "fase", "θz", "θ_z",
          "theta_z", "thetaz", "phase_angle"}       # (θz: Keysight's impedance analysers)
#: A phase named by its unit alone (``"Hz"  "Mag (dB)"  "deg"``, as MLSSA files head theirs).
_PHASE_UNIT = {"deg": "deg", "degree": "deg", "degrees": "deg", "°": "deg", "rad": "rad",
               "radian": "rad", "radians": "rad"}
_COMPLEX = {"complex", "response", "h", "g", "frf", "z", "h1", "h2", "hv", "txy", "tf",
            "impedance", "admittance"}
#: An impedance analyser's names of the impedance's parts, magnitude and phase (Gamry's
#: ``Zreal Zimag Zmod Zphz``, EC-Lab's ``Re(Z)/Ohm``, ZView's ``Z'`` and ``Z''``), with an
#: optional unit after them (``/Ohm``, ``(Ω)``, ``[deg]``): each to its role; the phase is
#: in degrees unless its unit says radians.
_IMPEDANCE = re.compile(
    r"(?P<name>re\s*\(\s*z\s*\)|im\s*\(\s*z\s*\)|\|\s*z\s*\||phase\s*\(\s*z\s*\)|z''|z\"|z'"
    r"|z_?real|z_?re|z_?imag|z_?img|z_?im|z_?mod|z_?phz|z_?phase)"
    r"\s*(?:/\s*(?P<din>[^/\[\]()]+)|[\[(]\s*(?P<unit>[^\])]*?)\s*[\])])?\s*")
_IMPEDANCE_ROLE = {"re": "re", "z'": "re", "zreal": "re", "z_real": "re", "zre": "re",
                   "z_re": "re", "im": "im", "z''": "im", 'z"': "im", "zimag": "im",
                   "z_imag": "im", "zimg": "im", "z_img": "im", "zim": "im", "z_im": "im",
                   "|z|": "mag", "zmod": "mag", "z_mod": "mag", "phase": "phase",
                   "zphz": "phase", "z_phz": "phase", "zphase": "phase", "z_phase": "phase"}


#: A field solver's column of a function of a quantity (Ansys HFSS / Circuit / Designer
#: exports: ``mag(S(Port1,Port1)) []``, ``dB(S(1,2))``, ``ang_deg(V(V1)) [deg]``,
#: ``re(Z(1,1))``): the function's role and unit; the quantity (a name with its
#: arguments: ``S(1,2)``, ``V(V1)``) is the column's channel.
_FUNCTION = re.compile(r"(mag|db|db20|ang_deg|ang_rad|cang_deg|cang_rad|re|im|real|imag)"
                       r"\(([a-z]\w*\(.*\))\)\s*(?:\[[^\]]*\])?")
_FUNCTION_ROLE = {"mag": ("mag", "lin"), "db": ("mag", "db"), "db20": ("mag", "db"),
                  "ang_deg": ("phase", "deg"), "cang_deg": ("phase", "deg"),
                  "ang_rad": ("phase", "rad"), "cang_rad": ("phase", "rad"),
                  "re": ("re", None), "real": ("re", None), "im": ("im", None),
                  "imag": ("im", None)}


def _impedance_column(s, label):
    """The :class:`Column` of an impedance analyser's name ``s`` (lower case), or None."""
    m = _IMPEDANCE.fullmatch(s)
    if m is None:
        return None
    name = re.sub(r"\s+", "", m.group("name"))
    role = _IMPEDANCE_ROLE.get(name.split("(")[0])
    unit = (m.group("din") or m.group("unit") or "").strip()
    if role == "phase":
        angle = _UNITS.get(unit.replace(" ", ""), "deg") if unit else "deg"
        return Column("phase", angle, label) if angle in ("deg", "rad") else None
    if unit and _UNITS.get(unit) not in (None, "lin"):      # "Zmod (dB)", "Z' (deg)"
        return Column("mag", "db", label) if role == "mag" and _UNITS[unit] == "db" else None
    return Column(role, "lin" if role == "mag" else None, label)


#: A network analyser's scattering parameter (``S21``) or receiver ratio (``A2/A1``,
#: ``B/R1``, as Keysight's analysers name a ratioed measurement), a complex response like
#: ``_COMPLEX``.
_SPARAM = re.compile(r"s\d\d|[abr]\d?/[abr]\d?")
#: A response's display format after its name, as Keysight's network analysers write a trace
#: (``S21 Log Mag(dB)``, ``S21 Lin Mag(U)``, ``S21 Phase(deg)``, ``S21 Real(U)``).
_FORMAT = re.compile(r"^(.+?)_(log_mag|lin_mag|phase|real|imag)$")
#: An S-parameter with its format glued on (``S21dB``, ``S21deg``, ``S21re``, ``S21_im``,
#: ``S21 mag``, as a VNA's script writes ``Freq,S11dB,S11deg,S21dB,...``): its column.
_SPARAM_PART = re.compile(r"^s\d\d_?(db|deg|rad|re|real|im|imag|mag)$")
_PART_COLUMN = {"db": ("mag", "db"), "deg": ("phase", "deg"), "rad": ("phase", "rad"),
                "re": ("re", None), "real": ("re", None), "im": ("im", None),
                "imag": ("im", None), "mag": ("mag", "lin")}
_SKIP = {"skip", "_", "-", "ignore", "coherence", "coh"}
#: Quantities an impedance analyser derives from the response and exports beside it as a
#: response's "unit" (``TR2: Impedance (Ls)``, as the Bode 100 writes a trace shown as a
#: series inductance): the series and parallel equivalent resistance, inductance and
#: capacitance, the quality and dissipation factors. Not the response in another form
#: (``Ls = Im Z / omega``): such a column is skipped, with a note (:data:`DERIVED`).
_DERIVED = {"rs", "ls", "cs", "rp", "lp", "cp", "q", "d"}
#: ``Column.unit`` of a skipped column that holds a quantity derived from the response.
DERIVED = "derived"
_LAYOUTS = ({"freq", "re", "im"}, {"freq", "mag", "phase"}, {"freq", "complex"})

#: How to name columns, quoted in error messages.
COLUMN_HELP = ("name each column: omega or w (rad/s), freq_hz or 'f [Hz]' (Hz), f/freq (unit "
               "from freq_unit); re, im; mag or mag_db with phase_deg or phase_rad; complex "
               "(literals like 1+2j); skip; a leading '-' negates re, im or a phase (-im "
               "for a column of -Im(Z))")


@dataclass(frozen=True)
class Column:
    """One column: ``role`` in freq/re/im/mag/phase/complex/skip, its ``unit`` (freq:
    'hz'/'rad/s'/None, mag: 'lin'/'db', phase: 'deg'/'rad'/None) and its ``label``;
    ``same``: for a skipped column that gives the response again in another form (an
    analyser's second trace), the role it would have had (:func:`one_layout`);
    ``negated``: the column holds minus the part or the phase (``-Im(Z)``, ``-Phase``, as
    impedance analysers write), which the reader negates back; ``scale``: a frequency
    column's values times ``scale`` are in its ``unit`` (1e6 for ``Freq [MHz]``)."""

    role: str
    unit: str = None
    label: str = ""
    same: str = None
    negated: bool = False
    scale: float = 1.0


#: What a leading minus may negate: a part or the phase (minus a frequency, a magnitude or
#: a complex column means nothing a file would write).
NEGATABLE = ("re", "im", "phase")


def unquoted(cell):
    """``cell`` stripped, and out of the quotes around it when it has a pair (``"Freq"``;
    not the primes of ``Z'`` or ``Z''``)."""
    cell = cell.strip()
    if len(cell) >= 2 and cell[0] == cell[-1] and cell[0] in "\"'":
        cell = cell[1:-1].strip()
    return cell


def written_values(cols, values):
    """``values`` (role to ndarray) with each column as its name says it was written taken
    back: minus a negated column (``-Im(Z)``), a prefixed frequency times its scale
    (``Freq [MHz]``)."""
    for c in cols:
        if c.role in values and (c.negated or c.scale != 1.0):
            values[c.role] = values[c.role] * (-c.scale if c.negated else c.scale)
    return values


def recognise(label):
    """The :class:`Column` a header cell or a name stands for, or None if unknown.

    A trace or channel prefix ending in a colon (``TR1: Gain (dB)``, as the Bode 100
    writes) is read past; a gain or response named with its part or angle as the unit
    (``Gain (Real)``, ``Gain (Imag)``, ``Gain (Degree)``) is that part or the phase."""
    head, colon, rest = label.rpartition(":")
    channel = _CHANNEL.match(label) or _TRACE_WORD.match(label)
    for name in (rest if colon and head.strip() and rest.strip() else None,
                 channel.groups()[-1] if channel else None):
        col = recognise(name) if name else None
        if col is not None:
            return replace(col, label=label.strip())
    s = unquoted(label).lower()
    if s[:1] in ("-", "\u2212") and s[1:].lstrip()[:1].isalpha():   # "-Im(Z)", "- Phase"
        col = recognise(s[1:].lstrip())
        return (replace(col, label=label.strip(), negated=not col.negated)
                if col is not None and col.role in NEGATABLE else None)
    col = _impedance_column(s, label.strip())
    if col is not None:
        return col
    m = _FUNCTION.fullmatch(s)
    if m:
        return Column(*_FUNCTION_ROLE[m.group(1)], label.strip())
    s = s.strip("\"'").strip()
    unit = ""
    m = _UNIT_RE.match(s)
    if m:
        s, unit = m.group(1).strip(), m.group(2).strip()
    elif "/" in s and s.partition("/")[2].replace(" ", "") in _UNITS.keys() | _PREFIXED_HZ:
        s, _, unit = s.partition("/")                                   # DIN: "f/Hz"
    scale = 1.0
    if unit.replace(" ", "") in _PREFIXED_HZ:     # "Freq [MHz]", "f/kHz" (and mHz: milli)
        found = re.search(r"([kmgt])\s*hz", label, re.IGNORECASE)
        milli = re.sub(r"\s", "", found.group(0)) == "mHz"              # as SI writes it
        scale, unit = (1e-3 if milli else _HZ_PREFIX[found.group(1).lower()]), "hz"
    s = re.sub(r"_part$", "", re.sub(r"[\s\-.]+", "_", s).strip("_"))   # "real part"
    part = _SPARAM_PART.fullmatch(s)
    if part and not unit:
        return Column(*_PART_COLUMN[part.group(1)], label.strip())
    if not unit:
        for suffix in _SUFFIXES:
            if s.endswith(suffix) and len(s) > len(suffix):
                s, unit = s[:-len(suffix)].rstrip("_"), suffix[1:]
                break
    unit = unit.replace(" ", "").replace("_", "/") if "/" in unit or unit in (
        "rad_s", "rad_sample") else unit.replace(" ", "")
    if _SPARAM.fullmatch(s):
        s = "response"
    fmt = _FORMAT.match(s)
    if fmt and (fmt.group(1) in _COMPLEX | _MAG or _SPARAM.fullmatch(fmt.group(1))):
        return _formatted(fmt.group(2), _UNITS.get(unit, "lin"), label.strip())
    if unit == "*" and s in _PHASE:     # WaveForms' "Channel 2 Phase (*)": * for the degree sign
        unit = "deg"
    if unit in _DERIVED and s in _COMPLEX | _MAG:
        return Column("skip", DERIVED, label.strip())
    if unit not in _UNITS:       # a physical unit ("Real [g/N]") scales re, im and |H|
        if s not in _RE | _IM | _COMPLEX | _MAG:
            return None
        unit = "db" if unit.startswith("db") else "lin" if s in _MAG else ""
    unit = _UNITS[unit]
    name = label.strip()
    if s in _MAG | _COMPLEX and unit in ("re", "im"):
        return Column(unit, None, name)
    if s in _MAG | _COMPLEX and unit in ("deg", "rad"):
        return Column("phase", unit, name)
    if s in _FREQ and unit in (None, "hz", "rad/s", "rad/sample"):
        return Column("freq", unit or _FREQ[s], name, scale=scale)
    if s in _SKIP and unit is None:
        return Column("skip", None, name)
    if s in _RE | _IM | _COMPLEX and unit is None:
        return Column("re" if s in _RE else "im" if s in _IM else "complex", None, name)
    if s in _DB and unit is None or s in _MAG and unit in (None, "db", "lin") \
            or s in _COMPLEX and unit in ("db", "lin"):
        return Column("mag", "db" if s in _DB or unit == "db" else "lin", name)
    if s in _PHASE and unit in (None, "deg", "rad"):
        return Column("phase", unit, name)
    if s in _PHASE_UNIT and unit is None:
        return Column("phase", _PHASE_UNIT[s], name)
    return None


def sparameter_of(label):
    """The scattering parameter or receiver ratio a column's label names, lower case
    (``"s21"`` of ``S21(REAL)`` or ``S21 Log Mag(dB)``, ``"a2/a1"`` of ``A2/A1(REAL)``), or
    None."""
    m = re.match(r"\s*[\"']?\s*(s\d\d|[abr]\d?/[abr]\d?)(?![\d])", label, re.IGNORECASE)
    if m:
        return m.group(1).lower()
    function = _FUNCTION.fullmatch(unquoted(label).lower())
    # a field solver's quantity: "v(v1)" of "mag(V(V1)) [V]", "s(12)" of "dB(S(1,2))"
    return re.sub(r"[\s,_]", "", function.group(2)) if function else None


def sparameters(labels):
    """The S-parameters (and receiver ratios) ``labels`` name, lower case, each once, in
    order."""
    return list(dict.fromkeys(p for p in map(sparameter_of, labels) if p))


def with_parameter(cols, parameter, where):
    """``cols`` with the response columns of the S-parameter (or receiver ratio)
    ``parameter`` kept and every other response column skipped; ``where`` names the file
    for the error.

    Raises
    ------
    OptionError
        ``parameter`` is not one the columns name (the message lists those they name).
    """
    want = str(parameter).strip().lower().replace(",", "").replace("_", "")
    named = sparameters(c.label for c in cols)
    if want not in named:
        what = (f"its columns name {', '.join(p.upper() for p in named)}" if named else
                "its columns name no S-parameter (S21(REAL), S21 Log Mag(dB), ...) or "
                "receiver ratio (A2/A1(REAL), ...)")
        raise OptionError(f"parameter={parameter!r} chooses an S-parameter of a Touchstone "
                          f"file or of a table whose columns name them; {where}: {what}")
    return tuple(c if c.role in ("freq", "skip") or sparameter_of(c.label) == want
                 else Column("skip", None, c.label) for c in cols)


def _formatted(fmt, unit, name):
    """The column of a response named with its display format (:data:`_FORMAT`), or None
    when the unit contradicts it; ``unit``: the label's unit read as a key of ``_UNITS``
    (a physical unit, ``U``: "lin")."""
    if fmt in ("real", "imag"):
        return Column("re" if fmt == "real" else "im", None, name) if unit not in (
            "db", "deg", "rad") else None
    if fmt == "phase":
        return Column("phase", unit, name) if unit in (None, "deg", "rad") else None
    if fmt == "log_mag":
        return Column("mag", "db", name) if unit in (None, "db") else None
    return Column("mag", "lin", name) if unit in (None, "lin") else None


def _quantity(label):
    """The measured quantity a response column names: ``gain`` of ``TR2: Gain (Degree)``,
    ``s21`` of ``S21 Log Mag(dB)``."""
    s = label.rpartition(":")[2].strip().lower()
    bare = unquoted(s).lstrip("-\u2212")               # (a negated column's quantity)
    s = s.strip("\"'").lstrip("-\u2212")
    if _IMPEDANCE.fullmatch(bare):
        return "z"                          # Re(Z), -Im(Z), |Z|, Zphz, Z'' ...
    function = _FUNCTION.fullmatch(bare)
    if function:
        return function.group(2).replace(" ", "")       # S(1,1) of dB(S(1,1))
    m = _UNIT_RE.match(s) or re.fullmatch(r"([^/]+)/[^/]*", s)          # "Phase/deg"
    s = (m.group(1) if m else s).strip()
    s = re.sub(r"[\s_\-]+(log[\s_\-]*mag|lin[\s_\-]*mag|phase|real|imag)$", "", s).strip()
    return "" if s in _PHASE | _DB else s       # a phase, or dB, of whatever quantity


def one_layout(cols):
    """``cols`` reduced to one layout when they give one response in several forms.

    Analysers export a measurement as several traces (the Bode 100: ``TR1: Gain (Real)``,
    ``TR1: Gain (Imag)``, ``TR1: Gain (dB)``, ``TR2: Gain (Degree)``, ...). When every
    response column names the same quantity, the first complete layout is read (real and
    imaginary, else a complex column, else magnitude and phase) and the other response
    columns become ``skip`` columns that remember their role (``Column.same``), so that
    the reader checks they agree. Otherwise, or with one layout already, ``cols`` as given.
    A response named as a complex quantity beside a phase column is its magnitude
    (``Impedance(ohms)`` and ``Phase(degrees)``, as Room EQ Wizard exports an impedance).
    """
    if None in cols:
        return cols
    if sorted(c.role for c in cols) == ["complex", "freq", "phase"]:
        cols = tuple(Column("mag", "lin", c.label) if c.role == "complex" else c
                     for c in cols)
    if _layout_problem(cols) is None:
        return cols
    freq = [c for c in cols if c.role == "freq"]
    resp = [c for c in cols if c.role not in ("freq", "skip")]
    if len(freq) != 1 or len({_quantity(c.label) for c in resp} - {""}) > 1:
        return cols
    roles = [c.role for c in cols]
    for want in (("re", "im"), ("complex",), ("mag", "phase")):
        if all(r in roles for r in want):
            keep = {roles.index(r) for r in want}          # the first column of each role
            return tuple(c if c.role in ("freq", "skip") or j in keep
                         else replace(c, role="skip", same=c.role)
                         for j, c in enumerate(cols))
    return cols


def _channel_of(label):
    """The channel or trace number a column's label starts with (``TR2: ...``,
    ``Channel 2 ...``), or None."""
    m = _CHANNEL_NO.match(label)
    return int(m.group(1)) if m else None


def complete_channels(cols):
    """``[(channel, columns=, name), ...]``: each channel or trace of a header that gives
    several whose columns form a complete layout (``Channel 2 Magnitude (dB)`` with
    ``Channel 2 Phase (deg)`` beside ``Channel 1 Magnitude (dB)``, as the Digilent
    WaveForms network analyser writes; ``CH1 ...`` and ``CH2 ...``, each complete, as a
    Siglent oscilloscope's Bode export), with the ``columns=`` string that reads it and its
    name as the header writes it (``CH1``): what an error can offer, since which channel
    is the system's response is the user's to say. Empty when the header does not have
    one frequency column and two or more channels, or a column is unknown."""
    if None in cols or [c.role for c in cols].count("freq") != 1:
        return []
    freq = next(c for c in cols if c.role == "freq")
    groups = {}
    for c in cols:
        if c.role not in ("freq", "skip"):
            groups.setdefault(_channel_of(c.label), []).append(c)
    if len(groups) < 2:
        return []
    return [(k, columns_option(tuple(
        c if c.role == "freq" or c.role != "skip" and _channel_of(c.label) == k
        else Column("skip") for c in cols)), _CHANNEL_NO.match(g[0].label).group(0).strip())
        for k, g in groups.items()
        if k is not None and _layout_problem([freq] + g) is None]


def columns_option(cols):
    """The ``columns=`` string that reads ``cols`` as they are read now (``skip`` for
    the others): ``'freq_hz,re,im,skip'``."""
    def name(c):
        if c.role == "freq":
            return {"hz": "freq_hz", "rad/s": "omega"}.get(c.unit, "f")
        if c.role == "mag":
            return "mag_db" if c.unit == "db" else "mag"
        if c.role == "phase":
            return {"deg": "phase_deg", "rad": "phase_rad"}.get(c.unit, "phase")
        return c.role
    return ",".join(("-" if c.negated and c.role in NEGATABLE else "") + name(c)
                    for c in cols)


def _layout_problem(cols):
    roles = [c.role for c in cols if c.role != "skip"]
    if len(set(roles)) != len(roles):
        dup = next(r for r in roles if roles.count(r) > 1)
        return f"two columns are {dup!r}"
    if set(roles) not in _LAYOUTS:
        why = ""
        if set(roles) == {"freq", "mag"}:
            why = ("; a magnitude alone cannot be fitted: the model's delay and zeros need "
                   "the phase too")
        elif set(roles) == {"freq", "re", "complex"}:
            as_im = [Column("im") if c.role == "complex" else c for c in cols]
            why = ("; if the column read as 'complex' holds the imaginary parts, name it im "
                   f"(columns='{columns_option(as_im)}')")
        return ("the columns must be one frequency and real+imaginary, magnitude+phase or "
                f"one complex column, got {', '.join(roles) or 'none'}{why}")
    return None


def parse_freq_unit(value):
    """'hz', 'rad/s' or None from a user's ``freq_unit`` (case-insensitive)."""
    if value is None:
        return None
    text = value.strip().lower().replace(" ", "") if isinstance(value, str) else None
    unit = {"hz": "hz", "rad/s": "rad/s", "rad_s": "rad/s", "rads": "rad/s",
            "rad/sec": "rad/s"}.get(text)
    if unit is None:
        raise OptionError(f"freq_unit must be 'Hz' or 'rad/s', got {value!r}; "
                          "pass freq_unit='Hz' (or --freq-unit hz) for frequencies in Hz")
    return unit


def parse_columns(columns):
    """A tuple of :class:`Column` from ``columns=`` (a string or a sequence), or None."""
    if columns is None:
        return None
    if isinstance(columns, tuple) and all(isinstance(c, Column) for c in columns):
        return columns
    if isinstance(columns, str):
        sep = "," if "," in columns else ";" if ";" in columns else None
        tokens = [t for t in (columns.split(sep) if sep else columns.split())]
    else:
        try:
            tokens = list(columns)
        except TypeError:
            raise OptionError(f"columns must be a string like 'f,re,im' or a sequence of "
                              f"names, got {columns!r}") from None
    cols = []
    for tok in tokens:
        col = recognise(tok) if isinstance(tok, str) else None
        if col is None:
            raise OptionError(f"columns: unknown column name {tok!r}; {COLUMN_HELP}")
        cols.append(col)
    problem = _layout_problem(cols)
    if problem:
        raise OptionError(f"columns={columns!r}: {problem}; e.g. columns='f,re,im' or "
                          "('freq_hz', 'mag_db', 'phase_deg')")
    return tuple(cols)


class ChannelChoice(DataError):
    """A table whose header gives several complete responses (an oscilloscope's channels,
    a network analyser's S-parameters, LTspice's traces): ``load`` reads one when told
    which; ``choices`` is ``[(name, load keywords), ...]``, one per response, for
    ``load_all`` to read them all."""

    def __init__(self, message, choices):
        super().__init__(message)
        self.choices = list(choices)


def several_responses(cells, cols, traces=()):
    """``(text, choices)`` for a header whose layout is not one response: the sentence an
    error adds (the ``columns=`` or ``parameter=`` that reads each response it gives) and
    the responses as ``[(name, load keywords), ...]`` (:class:`ChannelChoice`); the
    channel alone when only one is complete (``choices`` then empty).

    Parameters
    ----------
    cells : sequence of str
        The header's cells.
    cols : sequence of Column
        Their columns as recognised.
    traces : sequence of str
        LTspice's traces, when the header is its export.

    Returns
    -------
    (str, list)
    """
    text, choices = "", []
    channels = complete_channels(cols)
    if len(channels) == 1:
        text += (f"; to read channel {channels[0][0]}, the one whose columns make a "
                 f"response, pass columns='{channels[0][1]}'")
    elif channels:
        text += (f"; it gives {len(channels)} channels, each a complete response: which "
                 "is the system's response is yours to choose: pass " +
                 " or ".join(f"columns='{option}' to read {name}"
                             for _, option, name in channels) + " (command line --columns)")
        choices = [(name, {"columns": option}) for _, option, name in channels]
    named = [p.upper() for p in sparameters(cells)]
    if len(named) > 1:
        kinds = ("quantities" if any("(" in p for p in named) else
                 "S-parameters and ratios" if any("/" in p for p in named) else "S-parameters")
        text += (f"; its columns give {len(named)} {kinds} ({', '.join(named)}): pass "
                 f"parameter='{named[0]}' (command line --parameter {named[0]}) to read one")
        choices = choices or [(p, {"parameter": p}) for p in named]
    if traces:
        text += (f"; LTspice wrote {len(traces)} traces ({', '.join(traces)}): pass "
                 f"columns='freq_hz,complex{',skip' * (len(traces) - 1)}' to read "
                 f"{traces[0]} ('complex' in another trace's place reads that one)")
        choices = choices or [(t, {"columns": ",".join(
            ["freq_hz"] + ["complex" if j == k else "skip" for j in range(len(traces))])})
            for k, t in enumerate(traces)]
    return text, choices


#: A column of time stamps or sample numbers, by its name (units in brackets allowed).
_TIME = re.compile(r"^\s*(t|time|times|sample|samples|sample[ _]?(no|nr|number)|time[ _]?stamp)"
                   r"\s*([\[(].*[\])])?\s*$", re.IGNORECASE)


def time_column(label):
    """True if a header cell names time stamps or sample numbers (``time``, ``t [s]``,
    ``sample``), the first column of a file of time records or of an impulse response."""
    return bool(_TIME.match(label.strip().strip("\"'")))


def time_records(path, cells):
    """The message for a table whose header's first column counts time (``cells``)."""
    shown = ",".join(c.strip() for c in cells[:6]) + (",..." if len(cells) > 6 else "")
    return (f"{path!r} holds time-domain samples, not a frequency response: its first "
            f"column {cells[0].strip()!r} counts time (header {shown!r}); estimate the "
            "frequency response first: input and output records with 'freqid frf FILE "
            "--input NAME --output NAME' (the columns' names; see freqid frf --help), an "
            "impulse response by its Fourier transform (numpy.fft.rfft, frequencies "
            "numpy.fft.rfftfreq(n, 1/fs))")
