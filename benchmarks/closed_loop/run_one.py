"""Identify + diagnose one recording; print a JSON line (used by the closed-loop benchmark)."""
import json
import sys
import time

from flex_ident.diagnosis.closed_loop import diagnose
from flex_ident.identification.identify import IdentificationSettings, identify

bag, exp, out = sys.argv[1:4]
t0 = time.monotonic()
run = identify(bag, exp, out, IdentificationSettings(plots=False, diagnose=False))
t1 = time.monotonic()
res = diagnose(run.problem, run.result.params)
print(json.dumps({'bag': bag, 'declared': run.report['parameters'], 'error_declared': run.report['error_after'],
                  'identify_s': t1 - t0, 'diagnose_s': time.monotonic() - t1, **res}, default=str))
