"""Per-client token buckets for `locate`, where the app is served some other way.

`omninav serve` limits locate in nginx (server/nginx.py): one bucket per client for the whole
server, however many workers answer behind it (serve sets the workers' own LOCATE_RATE to 0). This
limiter applies where the app runs under a WSGI server of one's own, and in the tests: there it
limits per process, so N processes allow N times the rate.
"""

from __future__ import annotations

import threading
import time


class RateLimiter:
    def __init__(self, rate: float, burst: int, max_clients: int = 100_000):
        self.rate = float(rate)
        self.burst = float(burst)
        self.max_clients = max_clients
        self._buckets: dict[str, tuple[float, float]] = {}  # client -> (tokens, last time)
        self._lock = threading.Lock()

    def take(self, client: str, now: float | None = None) -> float:
        """0 if the client may go now, else the seconds until it may."""
        if self.rate <= 0:
            return 0.0
        now = time.monotonic() if now is None else now
        with self._lock:
            tokens, last = self._buckets.get(client, (self.burst, now))
            tokens = min(self.burst, tokens + (now - last) * self.rate)
            if tokens < 1.0:
                self._buckets[client] = (tokens, now)
                return (1.0 - tokens) / self.rate
            if len(self._buckets) >= self.max_clients and client not in self._buckets:
                # bound the memory: forget clients whose buckets are full again
                full = [c for c, (t, s) in self._buckets.items() if t + (now - s) * self.rate >= self.burst]
                for c in full:
                    del self._buckets[c]
            self._buckets[client] = (tokens - 1.0, now)
            return 0.0
