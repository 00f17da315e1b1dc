"""A meshmatch call on a thread of its own, so Blender stays responsive: the call releases the
GIL, reports progress into this object and stops when its token is cancelled."""

import threading

import meshmatch


class Job:
    """Run `fn(*args, **kwargs, progress=..., cancel=...)` on a background thread.

    `fraction` and `stage` follow its progress; `done` is set when it returns; then `result` or
    `error` holds the outcome. `cancel()` stops it (the call raises meshmatch.Cancelled).
    """

    def __init__(self, fn, *args, **kwargs):
        self.token = meshmatch.CancelToken()
        self.fraction = 0.0
        self.stage = "starting"
        self.result = None
        self.error = None
        self.done = False
        kwargs["progress"] = self._progress
        kwargs["cancel"] = self.token
        self._call = (fn, args, kwargs)
        self._thread = threading.Thread(
            target=self._run, args=self._call, daemon=True, name="meshmatch job"
        )

    def _progress(self, fraction, stage):
        self.fraction = fraction
        self.stage = stage

    def _run(self, fn, args, kwargs):
        try:
            self.result = fn(*args, **kwargs)
        except BaseException as e:  # reported on the main thread
            self.error = e
        finally:
            self.done = True

    def start(self):
        self._thread.start()
        return self

    def cancel(self):
        self.token.cancel()

    def wait(self, timeout=None):
        self._thread.join(timeout)
        return self.done

    def run_here(self):
        """Run on the calling thread (an operator's execute, a script, background mode)."""
        self._run(*self._call)
        return self
