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
@click.option("--raw-gnss", "raw_gnss", type=click.Path(path_type=Path, dir_okay=False), default=None,
              help="Also write raw GNSS observations (obs.rnx, nav.rnx, gnss_truth.csv) of the antenna's "
                   "trajectory with the settings of this YAML (docs/raw_gnss.md).")
@click.option("--gnss-format", "gnss_formats", multiple=True, type=click.Choice(["nmea", "ubx"]),
              help="Also write the GNSS fixes as a receiver writes them: nmea (gnss.nmea: GGA, RMC, GST) or ubx "
                   "(gnss.ubx: NAV-PVT, NAV-HPPOSLLH), with the formats' rounding; repeat for both. Needs an "
                   "absolute start.time (UNIX time, UTC).")
@quiet_option
def simulate(scenario, outdir, seed, perfect, duration, quiet, raw_gnss, gnss_formats):
    """Simulate SCENARIO.yaml: IMU increments, GNSS fixes and the exact truth (see docs/simulate.md).

    \b
    Example:
      sins simulate configs/scenarios/vehicle_drive.yaml -o run1 --seed 7
    """
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..sim.run import prepare, write_sim           # here, not at import: `sins simulate --help` is fast
    from ..sim.run import simulate as run_simulation
    from ..io.atomic import commit_outputs, prepare_output
    from ..sim.run import SIM_FILES
    for name in SIM_FILES:                             # before any work: a folder, permissions, an input
        prepare_output(outdir / name)
    raw_cfg = None
    if raw_gnss is not None:
        # raw GNSS loads only when asked for (--raw-gnss): the plain simulation does not need it
        from ..inputs import load_yaml
        from ..sim.raw_gnss import RAW_FILES, check_config
        raw_cfg = check_config(load_yaml(raw_gnss, "raw GNSS settings") or {}, str(raw_gnss))
        for name in RAW_FILES:
            prepare_output(outdir / name)
    prepared = prepare(scenario, perfect, duration)   # every check happens before anything is written
    sc = prepared.scenario
    gnss_formats = tuple(dict.fromkeys(gnss_formats))
    if gnss_formats:
        from ..sim.run import RECEIVER_FILES, check_receiver_formats   # the command's modules load when it runs
        check_receiver_formats(sc, gnss_formats)
        for fmt in gnss_formats:
            prepare_output(outdir / RECEIVER_FILES[fmt])
    with progress(prepared.n_imu, "simulate", quiet) as bar:
        result = run_simulation(prepared, seed=seed, perfect=perfect, progress=bar.update)
    paths = write_sim(result, outdir, gnss_formats)
    if raw_cfg is not None:
        from ..sim.raw_gnss import simulate_from_result, write_raw   # only with --raw-gnss
        raw = simulate_from_result(result, raw_cfg, seed if seed is not None else result.seed)
        paths += write_raw(raw, outdir)
        if not quiet:
            click.echo(f"raw GNSS: {len(raw.obs)} epochs in {outdir / 'obs.rnx'} at GPS time = scenario time + "
                       f"{raw.gps_offset:.0f} s (sins gnss spp ... --time-offset {-raw.gps_offset:.0f} gives the "
                       f"scenario's time base)", err=True)
    commit_outputs()
    log.info("wrote %s", ", ".join(str(p) for p in paths))
    if not quiet:
        click.echo(f"simulated {sc.name}: {len(result.imu)} IMU samples at {sc.imu_rate:g} Hz, "
                   f"{len(result.gnss)} GNSS fixes, {result.imu.time[-1] - result.imu.t0:g} s -> {outdir}",
                   err=True)
