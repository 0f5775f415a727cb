"""``sins allan``: Allan deviation of a static IMU log, fitted noise terms, and a sensor description."""
from __future__ import annotations

import contextlib
from pathlib import Path

import click

from .base import main, progress, quiet_option
from ..units import UG


@main.command("allan")
@click.argument("log", type=click.Path(path_type=Path))
@click.option("--imu-topic", default=None, help="IMU topic in a ROS bag / MCAP log.")
@click.option("--start", type=float, default=None, help="Start of the static stretch, log time (s).")
@click.option("--end", type=float, default=None, help="End of the static stretch, log time (s).")
@click.option("--config", "config_path", type=click.Path(path_type=Path), default=None,
              help="Config YAML: imu/ros sections of the navigation config (columns, units, mounting); "
                   "align.static_check sets the rest limits.")
@click.option("--name", default=None, help="Sensor name written to sensor.yaml (default: the log's stem).")
@click.option("--per-decade", type=click.IntRange(min=2, max=50), default=10, show_default=True,
              help="Cluster times per decade.")
@click.option("-o", "--output", "outdir", required=True, type=click.Path(path_type=Path, file_okay=False),
              help="Output directory: sensor.yaml, allan.csv, fit.csv, allan.png.")
@quiet_option
def allan_cmd(log, imu_topic, start, end, config_path, name, per_decade, outdir, quiet):
    """Allan deviation of a static IMU log: noise terms and a sensor.yaml in the presets' schema.

    \b
      sins allan static.csv -o imu_noise/
      sins allan log.bag --imu-topic /imu/data --start 1432235500 --end 1432239100 -o imu_noise/

    The log must be at rest (the check of sins align: 1 s mean rate and specific
    force); the fit needs hours for the bias terms.  sensor.yaml is in the schema
    of the shipped presets (sinscli.sensors.load_sensor; a scenario's imu.sensor takes its path).
    """
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..align.options import build_options, load_align_config
    from ..allan.output import plot_allan, write_allan_csv, write_fit_csv, write_sensor_yaml
    from ..allan.pipeline import characterize
    from ..config import merge
    from ..io.readers import read_imu
    from ..report.report import staged_dir

    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    from ..io.atomic import prepare_output
    prepare_output(outdir, directory=True)      # before any work: a file, no permission
    cfg, al = load_align_config(config_path)
    cfg = merge(cfg, "ros", imu_topic=imu_topic)
    opts = build_options(al, str(config_path) if config_path else "command line")
    imu = read_imu(log, cfg, allow_gaps=False)
    with contextlib.ExitStack() as stack:
        bar = {}

        def on_sizes(k):
            bar["bar"] = stack.enter_context(progress(k, "allan", quiet))

        res = characterize(imu, start, end, opts.static_rate, opts.static_accel, opts.static_block,
                           per_decade=per_decade, progress=lambda k: bar["bar"].update(k), on_sizes=on_sizes)
    for note in res.notes:
        click.echo(f"sins: note: {note}", err=True)
    sensor_name = name or Path(log).stem
    with staged_dir(outdir) as tmp:
        write_sensor_yaml(tmp / "sensor.yaml", res, sensor_name)
        write_allan_csv(tmp / "allan.csv", res)
        write_fit_csv(tmp / "fit.csv", res)
        plot_allan(tmp / "allan.png", res, f"sins allan: {Path(log).name}, {res.duration / 3600.0:.3g} h at "
                                           f"{1.0 / res.tau0:.4g} Hz")
    from ..io.atomic import commit_outputs  # numpy: the atomic writers load when outputs are written, not for --help (tests/test_cli_startup.py)
    commit_outputs()
    if not quiet:
        # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
        import numpy as np
        from ..allan.fit import TERMS
        g = [f.white for f in res.fits[:3]]
        a = [f.white for f in res.fits[3:]]
        click.echo(f"sins: allan: {res.n} samples, {res.duration:.6g} s; ARW {np.degrees(np.mean(g)) * 60:.4g} "
                   f"deg/sqrt(h), VRW {np.mean(a) / UG:.4g} micro-g/sqrt(Hz) (axis means) -> "
                   f"{outdir}/sensor.yaml", err=True)
        names = {"quantization": "quantization", "white": "random walk (ARW/VRW)",
                 "gauss_markov": "bias instability (Gauss-Markov)", "rate_random_walk": "rate random walk"}
        seen = ", ".join(f"{names[t]} on {sum(f.identified[t] for f in res.fits)}/6 axes" for t in TERMS)
        click.echo(f"sins: allan: identified from this {res.duration / 3600.0:.3g} h log: {seen} "
                   "(a bias term needs a log of about 17 of its correlation times)", err=True)
