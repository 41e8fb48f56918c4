"""The search of a fit (the unit cube of the parameters, CMA-ES or a bracket) and the Dask
cluster its evaluations run on."""
import math
import os

import numpy as np


class Space:
    """Parameters and bounds; a candidate is a point of the unit cube, logarithmic along a
    parameter whose bounds are positive and a decade or more apart."""

    def __init__(self, bounds):
        self.names = list(bounds)
        self.lo = np.array([float(bounds[n][0]) for n in self.names])
        self.hi = np.array([float(bounds[n][1]) for n in self.names])
        self.log = (self.lo > 0) & (self.hi >= 10 * self.lo)

    def unit(self, values):
        """The point of the unit cube of `values` (a dict)."""
        x = np.array([float(values[n]) for n in self.names])
        with np.errstate(divide="ignore", invalid="ignore"):
            geo = np.log(np.maximum(x, 1e-300) / self.lo) / np.log(self.hi / self.lo)
            lin = (x - self.lo) / (self.hi - self.lo)
        return np.where(self.log, geo, lin)

    def values(self, u):
        u = np.clip(np.asarray(u, dtype=float), 0.0, 1.0)
        lin = self.lo + u * (self.hi - self.lo)
        geo = np.exp(np.log(np.where(self.log, self.lo, 1.0)) +
                     u * np.log(np.where(self.log, self.hi / np.where(self.log, self.lo, 1.0), 1.0)))
        return dict(zip(self.names, np.where(self.log, geo, lin).tolist()))


class Bracket:
    """One parameter: `population` points across the interval, then the interval narrowed to a
    grid step either side of the best."""

    def __init__(self, population):
        self.population = max(3, population)
        self.lo, self.hi = 0.0, 1.0

    def ask_all(self):
        return [np.array([u]) for u in np.linspace(self.lo, self.hi, self.population)]

    def tell(self, points, costs):
        best = float(points[int(np.argmin(costs))][0])
        step = (self.hi - self.lo) / (self.population - 1)
        self.lo, self.hi = max(0.0, best - step), min(1.0, best + step)

    def should_stop(self):
        return self.hi - self.lo < 1e-5


class Cma:
    """CMA-ES over the unit cube (python3-cmaes)."""

    def __init__(self, dims, population, seed):
        from cmaes import CMA
        self.opt = CMA(mean=np.full(dims, 0.5), sigma=0.25, bounds=np.array([[0.0, 1.0]] * dims),
                       seed=seed, population_size=population)

    @property
    def population(self):
        return self.opt.population_size

    def ask_all(self):
        return [self.opt.ask() for _ in range(self.opt.population_size)]

    def tell(self, points, costs):
        self.opt.tell([(p, c if math.isfinite(c) else 1e6) for p, c in zip(points, costs)])

    def should_stop(self):
        return self.opt.should_stop()


class Cluster:
    """A Dask client: on the scheduler at `address`, or on a local cluster of `workers`
    single-threaded processes."""

    def __init__(self, address=None, workers=None):
        from distributed import Client, LocalCluster
        self.local = None
        if address:
            self.client = Client(address, timeout="30s")
        else:
            self.local = LocalCluster(n_workers=workers or os.cpu_count(), threads_per_worker=1,
                                      processes=True, dashboard_address=None)
            self.client = Client(self.local)

    def map(self, fn, items, **kwargs):
        futures = self.client.map(fn, items, pure=False, retries=3, **kwargs)
        return self.client.gather(futures)

    def close(self):
        self.client.close()
        if self.local is not None:
            self.local.close()
