"""A progress bar over simulated time: :class:`TimeProgress`."""

from tqdm import tqdm

from .interrupts import check as check_interrupts


class TimeProgress:
    """A progress bar over the simulated time (s) as a context: gives ``step(t)``, which moves it to ``t`` (and ends the command there after a Ctrl-C that was swallowed); it shows
    the time left as tqdm estimates it from the rate so far. ``reached``: the last ``t`` given (s)."""

    def __init__(self, label, total, shown):
        self.reached = 0.0
        self.bar = tqdm(total=total, desc=label, unit="s", disable=not shown, leave=False,
                        bar_format="{desc}: {percentage:3.0f}% |{bar}| {n:.4g}/{total:g} s [{elapsed}<{remaining}]")

    def __enter__(self):
        return self.step

    def step(self, t):
        check_interrupts()
        self.reached = t
        self.bar.update(min(t, self.bar.total) - self.bar.n)

    def __exit__(self, *exc):
        self.bar.close()
