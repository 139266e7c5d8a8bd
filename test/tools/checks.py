"""A list of named checks for the result-directory tests: each printed as ok or FAIL, the
failures kept for the exit status."""


class Checks:
    def __init__(self):
        self.failures = []

    def __call__(self, ok, what):
        print(("ok   " if ok else "FAIL ") + what)
        if not ok:
            self.failures.append(what)

    def status(self):
        return 1 if self.failures else 0
