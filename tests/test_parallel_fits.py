"""fit(n_jobs=2) (issue 30 item 3): the independent fits run in forked workers, one per
integrator contender and, where the rational starts do not decide the gain sign, one per
sign; the integrator's rational starts and those of the non-minimum-phase check go to
workers when they are slow. The result is the serial one, bit for bit.

Each run is a fresh interpreter: workers are forked only where no other thread runs, as
in a user's script (this test session may run threads)."""

import json
import multiprocessing
import subprocess
import sys

import pytest

import freqid_casadi as fc
from freqid_casadi.experiment import robot_arm

pytestmark = pytest.mark.skipif("fork" not in multiprocessing.get_all_start_methods(),
                                reason="this platform cannot fork: n_jobs runs the fits here")

_FORKS = """
import json, sys, freqid_casadi as fc
from freqid_casadi import _workers
used = []
original = _workers.fork_submit
_workers.fork_submit = lambda *a: used.append(len(a[2])) or original(*a)
"""


def _run(code, timeout=300):
    out = subprocess.run([sys.executable, "-c", _FORKS + code], capture_output=True,
                         text=True, check=True, timeout=timeout).stdout
    return json.loads(out.strip().splitlines()[-1])


_SIGNS = """
from freqid_casadi.experiment import robot_arm
records = []
res = fc.fit(robot_arm().data, n_sections=1, integrator=int(sys.argv[1]), n_jobs=2,
             progress=records.append)
print(json.dumps({"used": used, "model": res.model.to_json(), "records": len(records),
                  "gain_sign": res.details.get("gain_sign"),
                  "codes": [d.code for d in res.diagnostics], "rms": res.rms_rel_error}))
"""


@pytest.mark.parametrize("k", [0, -1])
def test_both_gain_signs_in_two_workers_give_the_serial_fit(k):
    # the robot arm at one section, k given: the rational starts do not decide the sign
    # (the fit records "by": "fits"), so both signs are fitted, here in two workers
    serial = fc.fit(robot_arm().data, n_sections=1, integrator=k)
    assert serial.details["gain_sign"]["by"] == "fits"
    code = _SIGNS.replace("int(sys.argv[1])", str(k))
    run = _run(code)
    assert 2 in run["used"]                               # the two signs' fits
    assert run["model"] == serial.model.to_json()
    assert run["rms"] == serial.rms_rel_error
    assert run["gain_sign"] == json.loads(json.dumps(serial.details["gain_sign"]))
    assert run["codes"] == [d.code for d in serial.diagnostics]
    assert run["records"] >= len(serial.stages)          # both signs' records shown


_CONTENDERS = """
from freqid_casadi.experiment import robot_arm
from freqid_casadi.fitting import start
# the integrator's starts stay here (by default they go to workers after one that took
# MIN_FORKED_JOB seconds: on a loaded machine the robot arm's first start did, and the
# first pool was then theirs), so that the first pool is the contenders' and signs'
start.MIN_FORKED_JOB = float("inf")
res = fc.fit(robot_arm().data, n_sections=1, n_jobs=2)
print(json.dumps({"used": used, "model": res.model.to_json(),
                  "integrator": res.details["integrator"],
                  "gain_sign": res.details.get("gain_sign"), "rms": res.rms_rel_error}))
"""


def test_contenders_and_signs_share_the_workers():
    # integrator="auto" on the robot arm at one section: several contenders, some with an
    # undecided sign; each (contender, sign) fit is one job of one pool of workers
    serial = fc.fit(robot_arm().data, n_sections=1)
    rec = serial.details["integrator"]
    run = _run(_CONTENDERS)
    assert run["used"][0] > len(rec["contenders"]) > 1    # signs split too
    assert run["model"] == serial.model.to_json()
    assert run["rms"] == serial.rms_rel_error
    assert run["integrator"] == json.loads(json.dumps(rec))
    assert run["gain_sign"] == json.loads(json.dumps(serial.details.get("gain_sign")))


_SIGN_SUBSET = """
from freqid_casadi.fitting import core_fits
core_fits.SETTLE_ABOVE, core_fits.SETTLE_POINTS = 50, 34
res = fc.fit(fc.systems.measured("ring_slot_s11"), n_sections=1, integrator=False,
             n_jobs=int(sys.argv[1]))
print(json.dumps({"used": used, "model": res.model.to_json(),
                  "gain_sign": res.details.get("gain_sign"), "rms": res.rms_rel_error}))
"""


def test_the_signs_on_a_subset_in_two_workers_give_the_serial_fit():
    # the ring slot at one section with the subset's thresholds lowered (34 of its 101
    # points, tests/test_status.py): the two signs' subset fits run in two workers, the
    # kept sign's fit on all points here; the result and its record are the serial ones
    serial = _run(_SIGN_SUBSET.replace("int(sys.argv[1])", "1"))
    run = _run(_SIGN_SUBSET.replace("int(sys.argv[1])", "2"))
    assert serial["used"] == [] and 2 in run["used"]
    assert serial["gain_sign"]["settled_on"] == {"points": 34, "of": 101}
    assert run["model"] == serial["model"] and run["rms"] == serial["rms"]
    assert run["gain_sign"] == serial["gain_sign"]


_ORIGIN = """
from freqid_casadi._workers import allow_jobs
from freqid_casadi.fitting import start
from freqid_casadi.fitting.origin import choose_origin_order
from freqid_casadi.studies.measured import actuator_frf
start.MIN_FORKED_JOB = 0.0          # every start after the first to a worker, however fast
data = actuator_frf().data
with start.rational_start_memo(), allow_jobs(int(sys.argv[1])):
    k, record = choose_origin_order(data, 2, True, "second-order", "minimum-phase")
    memo = len(start._MEMO.get())
print(json.dumps({"used": used, "record": record, "memo": memo}))
"""


def test_integrator_starts_in_workers_give_the_serial_choice_and_share_their_work():
    # the actuator at 2 sections: the starts of the slope's candidates after the first run
    # in workers (forced here; by default only when the first took MIN_FORKED_JOB); the
    # choice is the serial one, and the workers' rational starts and vector fittings reach
    # this process's memo (the fits after the choice reuse them)
    serial = _run(_ORIGIN.replace("int(sys.argv[1])", "1"))
    run = _run(_ORIGIN.replace("int(sys.argv[1])", "2"))
    assert serial["used"] == []
    assert run["used"] and sum(run["used"]) < len(run["record"]["candidates"])
    assert run["record"] == serial["record"]
    assert run["memo"] == serial["memo"] > 0


_PHASE_CHECK = """
import warnings
from freqid_casadi._workers import allow_jobs
from freqid_casadi.fitting import start
from freqid_casadi.fitting.diagnostics import check_minimum_phase
from freqid_casadi.systems import case
warnings.simplefilter("ignore")
start.MIN_FORKED_JOB = 0.0          # every start after the first to a worker, however fast
c = case(30, 2026, max_points=400)
res = fc.fit(c.data, n_sections=c.n_sections)
out = {}
for jobs in (1, 2):
    with start.rational_start_memo(), allow_jobs(jobs):
        out[jobs] = [(d.code, d.message, d.values) for d in check_minimum_phase(
            res.model, res.data, res.max_rel_error, res.rms_rel_error)]
print(json.dumps({"used": used, "serial": out[1], "workers": out[2]}))
"""


def test_the_phase_checks_starts_in_workers_give_the_serial_diagnostic():
    # holdout modal-noncollocated-30 (test_diagnostics): the check's fallback runs the
    # rational start with free zeros at two k (and with minimum-phase zeros at five); each
    # k's starts in a worker give the serial diagnostic, values and message alike
    run = _run(_PHASE_CHECK)
    assert run["used"]                                   # the check's starts forked
    assert run["serial"] and run["serial"][0][0] == "non-minimum-phase"
    assert run["serial"][0][2]["free_zeros_fit"] == "rational start"
    assert run["workers"] == run["serial"]
