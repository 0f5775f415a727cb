"""Batches: execution back ends (local pool, Dask), finished jobs and resume, batch comparisons, Monte Carlo
studies, the results dataset and the statistics over runs."""
