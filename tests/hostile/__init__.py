"""The hostile-input sweep (issue 22): every program of the project on inputs a careless or hostile user gives it.

`case.py` says what a case is, `fixtures.py` builds the good files once per session, `inputs.py` turns them into
bad ones, `dynid_cases.py` and `c_cases.py` list the cases, `run.py` runs the programs; the test is
tests/test_hostile_inputs.py, and docs/fuzzing.md ("The hostile-input sweep") describes it.
"""
