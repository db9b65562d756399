"""Counting checks for the interop scripts: each script's pass/fail tally and closing line."""

import sys


class Tally:
    """Counts checks; a failed one is reported on stderr under the script's name."""

    def __init__(self, name):
        self.name = name
        self.passed = 0
        self.failed = 0

    def check(self, ok, what):
        """Counts one check; returns `ok` so a caller can stop on a failed prerequisite."""
        if ok:
            self.passed += 1
        else:
            self.failed += 1
            print(f"{self.name}: FAIL: {what}", file=sys.stderr)
        return ok

    def finish(self, label="interop"):
        """Prints `<label>: N passed, M failed` and returns the exit status (1 on any failure)."""
        print(f"{label}: {self.passed} passed, {self.failed} failed")
        return 1 if self.failed else 0
