"""``sins simulate``: a scenario YAML -> imu.csv, gnss.csv, truth.csv, init.yaml with exact truth."""
from __future__ import annotations

from pathlib import Path

import click

from .base import log, main, progress, quiet_option


@main.command("simulate")
@click.argument("scenario", type=click.Path(path_type=Path, dir_okay=False))
@click.option("-o", "--output", "outdir", required=True, type=click.Path(path_type=Path, file_okay=False),
              help="Output directory (created; imu.csv, gnss.csv, truth.csv, init.yaml in it are replaced).")
@click.option("--seed", type=click.IntRange(min=0), default=None,
              help="Random seed of the sensor and GNSS errors (default: the scenario's 'seed', else 0).")
@click.option("--perfect", is_flag=True,
              help="Error-free IMU and GNSS whatever the scenario says (for checking algorithms on the truth).")
@click.option("--duration", type=float, default=None,
              help="Simulate only the first SECONDS of the scenario (default: all of it).")
@quiet_option
def simulate(scenario, outdir, seed, perfect, duration, quiet):
    """Simulate SCENARIO.yaml: IMU increments, GNSS fixes and the exact truth (see docs/simulate.md).

    \b
    Example:
      sins simulate configs/scenarios/vehicle_drive.yaml -o run1 --seed 7
    """
    from ..sim.run import prepare, write_sim           # here, not at import: `sins simulate --help` is fast
    from ..sim.run import simulate as run_simulation

    from ..io.atomic import commit_outputs, prepare_output
    from ..sim.run import SIM_FILES
    for name in SIM_FILES:                             # before any work: a folder, permissions, an input
        prepare_output(outdir / name)
    prepared = prepare(scenario, perfect, duration)   # every check happens before anything is written
    sc = prepared.scenario
    with progress(prepared.n_imu, "simulate", quiet) as bar:
        result = run_simulation(prepared, seed=seed, perfect=perfect, progress=bar.update)
    paths = write_sim(result, outdir)
    commit_outputs()
    log.info("wrote %s", ", ".join(str(p) for p in paths))
    if not quiet:
        click.echo(f"simulated {sc.name}: {len(result.imu)} IMU samples at {sc.imu_rate:g} Hz, "
                   f"{len(result.gnss)} GNSS fixes, {result.imu.time[-1] - result.imu.t0:g} s -> {outdir}",
                   err=True)
