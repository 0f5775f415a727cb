"""``sins gnss spp OBS --nav NAV -o gnss.csv``: single-point positions and Doppler velocities from raw
observations (RINEX or u-blox UBX) and broadcast ephemerides."""
from __future__ import annotations

from pathlib import Path

import click

from .base import _Command, log, main, progress, quiet_option


@main.group("gnss")
def gnss_group():
    """Raw GNSS observations: single-point positioning (see docs/raw_gnss.md)."""


@gnss_group.command("spp", cls=_Command)
@click.argument("obs_path", metavar="OBS", type=click.Path(path_type=Path))
@click.option("--nav", "nav_paths", multiple=True, type=click.Path(path_type=Path),
              help="RINEX navigation file(s) (repeat for several); optional for a UBX log (its RXM-SFRBX).")
@click.option("-o", "--output", required=True, type=click.Path(path_type=Path, dir_okay=False),
              help="GNSS CSV (docs/formats.md columns, 1-sigma, nsat, pdop, excluded).")
@click.option("--systems", default=None, help="Systems to use, letters of GECJ (default: every one observed).")
@click.option("--elev-mask", type=click.FloatRange(0.0, 90.0), default=15.0, show_default=True,
              help="Elevation mask (deg).")
@click.option("--iono", type=click.Choice(["auto", "klobuchar", "iflc", "off"]), default="auto", show_default=True,
              help="Ionosphere: the ionosphere-free combination where every satellite of a system has two "
                   "frequencies, else Klobuchar (auto = iflc); klobuchar only; or none.")
@click.option("--no-tropo", is_flag=True, help="No troposphere model (Saastamoinen + DO-229 mapping by default).")
@click.option("--no-fde", is_flag=True, help="No chi-square fault detection and exclusion.")
@click.option("--fde-alpha", type=click.FloatRange(1e-9, 0.5), default=1e-3, show_default=True,
              help="False-alarm probability of the chi-square test.")
@click.option("--code-sigma", type=click.FloatRange(min=0.01, max=100.0), default=0.3, show_default=True,
              help="Pseudorange noise a = b (m) of sigma^2 = a^2 + b^2/sin^2(el), scaled up below C/N0 45 dB-Hz.")
@click.option("--doppler-sigma", type=click.FloatRange(min=0.001, max=100.0), default=0.1, show_default=True,
              help="Range-rate noise at the zenith (m/s).")
@click.option("--smooth-code", type=click.FloatRange(0.0, 3600.0), default=100.0, show_default=True,
              help="Carrier smoothing of the pseudoranges (Hatch filter, RTCA DO-229's 100 s) over SECONDS; 0: "
                   "raw snapshot pseudoranges.")
@click.option("--time-offset", type=float, default=0.0, show_default=True,
              help="Seconds added to every output time (e.g. minus the GPS time of a simulated scenario's start).")
@click.option("--time", "time_base", type=click.Choice(["gps", "tow"]), default="gps", show_default=True,
              help="Output time: GPS seconds since 1980-01-06, or seconds of the GPS week.")
@quiet_option
def spp_cmd(obs_path, nav_paths, output, systems, elev_mask, iono, no_tropo, no_fde, fde_alpha, code_sigma,
            doppler_sigma, smooth_code, time_offset, time_base, quiet):
    """Single-point positions and Doppler velocities of every epoch of OBS (RINEX 2.11/3.x observations,
    gzip or Hatanaka compressed, or a u-blox UBX log) with the broadcast ephemerides of NAV, written as a
    docs/formats.md GNSS CSV that `sins navigate --gnss` fuses as it is.

    \b
    Example:
      sins gnss spp slac1350.20o --nav brdc1350.20n -o gnss.csv
    """
    # the command's modules load when it runs: --help stays light (tests/test_cli_startup.py)
    import numpy as np
    from ..errors import SinsError
    from ..gnss import spp as S
    from ..gnss.pipeline import parse_systems, run_spp_chunks
    from ..gnss.timesys import SECONDS_PER_WEEK
    from ..io.atomic import prepare_output
    from ..io.raw_input import read_raw
    from ..io.spp_csv import write_spp_csv

    prepare_output(output)
    sys_list = parse_systems(systems)
    obs, nav = read_raw(obs_path, nav_paths)
    if len(obs) == 0:
        raise SinsError(f"{obs_path}: no observation epochs")
    opts = S.spp_options(elev_mask_deg=elev_mask, iono=iono, tropo=not no_tropo, code_a=code_sigma,
                         code_b=code_sigma, doppler_sigma=doppler_sigma, fde=not no_fde)
    with progress(len(obs), "spp", quiet) as bar:
        res = run_spp_chunks(obs, nav, sys_list, opts, fde_alpha, bar.update, smooth=smooth_code)
    ok = res.fix
    if not ok.any():
        counts = np.bincount(res.rec_status, minlength=7)
        raise SinsError(f"{obs_path}: no epoch could be solved ({len(obs)} epochs; satellite records: "
                        f"{counts[S.NO_EPH]} without an ephemeris, {counts[S.BELOW_MASK]} below the mask, "
                        f"{counts[S.SYSTEM_OFF]} of systems not used)")
    lat, lon, h, vel, std, std_v = res.enu()
    t = res.solution_time()
    if time_base == "tow":
        t = t - np.floor(res.time / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
    t = t + time_offset
    data = {"time": t[ok], "lat": lat[ok], "lon": lon[ok], "height": h[ok]}
    with_vel = bool(res.vel_ok[ok].all())
    if with_vel:
        for i, c in enumerate(("vel_e", "vel_n", "vel_u")):
            data[c] = vel[ok, i]
    for i, c in enumerate(("std_e", "std_n", "std_u")):
        data[c] = std[ok, i]
    if with_vel:
        for i, c in enumerate(("std_vel_e", "std_vel_n", "std_vel_u")):
            data[c] = std_v[ok, i]
    elif res.vel_ok[ok].any():
        log.warning("%s: %d of %d fixes have no Doppler velocity (fewer than 4 Doppler measurements): the "
                    "velocity columns are left out", obs_path, int((~res.vel_ok[ok]).sum()), int(ok.sum()))
    data["nsat"] = res.nsat[ok].astype(np.float64)
    data["pdop"] = res.pdop[ok]
    excluded = [x for x, k in zip(res.excluded_text(), ok) if k]
    write_spp_csv(output, data, excluded)
    if not quiet:
        n_ex = int((res.rec_status == S.EXCLUDED).sum())
        failed = int((res.status == S.CHI2_FAILED).sum())
        few = int((res.status == S.TOO_FEW).sum()) + int((res.status == S.NO_CONVERGENCE).sum())
        hs = np.hypot(std[ok, 0], std[ok, 1])
        click.echo(f"sins: gnss spp {obs_path}: {int(ok.sum())} fixes of {len(obs)} epochs "
                   f"({few} with too few satellites, {failed} failing the chi-square test after exclusion); "
                   f"satellites used {res.nsat[ok].mean():.1f} on average, PDOP median {np.median(res.pdop[ok]):.2f}, "
                   f"{n_ex} satellite measurements excluded; horizontal 1-sigma median {np.median(hs):.2f} m"
                   f"{'; Doppler velocity on every fix' if with_vel else ''} -> {output}", err=True)
