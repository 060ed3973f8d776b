"""What each peer script reports: a line per check, and its exit status."""

import sys
import time
import traceback


class Checks:
    """Runs named checks; each passes, fails with a detail, or raises."""

    def __init__(self, name):
        self.name = name
        self.failed = []
        self.passed = 0

    def check(self, what, ok, detail=""):
        if ok:
            self.passed += 1
            print(f"ok   {what}", flush=True)
        else:
            self.failed.append(what)
            print(f"FAIL {what}: {detail}", flush=True)
        return ok

    def equal(self, what, got, want):
        return self.check(what, got == want, f"got {got!r}, want {want!r}")

    def run(self, what, fn):
        """Runs fn(); an exception fails the check with its message."""
        try:
            fn()
        except Exception as e:  # noqa: BLE001 - every failure is a finding
            self.check(what, False, f"{type(e).__name__}: {e}")
            traceback.print_exc(file=sys.stdout)

    def done(self):
        print(f"{self.name}: {self.passed} passed, {len(self.failed)} failed", flush=True)
        sys.exit(1 if self.failed else 0)


# A loaded test machine may not run a fake device (or this script) for a while: the checks
# judge what the device answers, so they wait this many times longer than a quiet machine
# needs before they call a missing answer a failure.
PATIENCE = 5.0


def wait_for(pred, timeout, step=0.01):
    """Polls pred() until it holds or PATIENCE x timeout seconds pass; whether it held."""
    end = time.monotonic() + PATIENCE * timeout
    while time.monotonic() < end:
        if pred():
            return True
        time.sleep(step)
    return pred()
