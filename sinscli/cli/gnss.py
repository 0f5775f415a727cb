"""``sins gnss spp OBS --nav NAV -o gnss.csv``: single-point positions and Doppler velocities from raw
observations (RINEX or u-blox UBX) and broadcast ephemerides."""
from __future__ import annotations

from pathlib import Path

import click

from .base import _Command, log, main, progress, quiet_option

# the output time bases of ``sins gnss spp --time`` and how the summary names them
TIME_BASES = {"gps": "GPS seconds since 1980-01-06 00:00:00 GPST", "tow": "seconds of the GPS week",
              "utc": "UTC-based UNIX seconds", "posix-gpst": "GPS time as POSIX seconds (UNIX + GPS-UTC leap seconds)"}


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
@click.option("--time", "time_base", type=click.Choice(list(TIME_BASES)), default="gps", show_default=True,
              help="Output time base: gps = GPS seconds since 1980-01-06 00:00:00 GPST; tow = seconds of the GPS "
                   "week; utc = UTC-based UNIX seconds (leap seconds removed); posix-gpst = GPS time counted from "
                   "the UNIX epoch (UNIX seconds plus the GPS-UTC leap seconds, as IMU logs with imu.time_system "
                   "gps are stamped).  docs/formats.md.")
@click.option("--tdcp", is_flag=True,
              help="Velocity from the carrier phase differenced between epochs (TDCP: central differences of the "
                   "receiver's displacement, cycle slips tested), instead of the Doppler's.")
@click.option("--carrier-sigma", type=click.FloatRange(min=1e-4, max=1.0), default=0.003, show_default=True,
              help="With --tdcp: carrier-phase sigma (m) at C/N0 45 dB-Hz and above (its variance grows as 1/C/N0 "
                   "below).")
@quiet_option
def spp_cmd(obs_path, nav_paths, output, systems, elev_mask, iono, no_tropo, no_fde, fde_alpha, code_sigma,
            doppler_sigma, smooth_code, time_offset, time_base, tdcp, carrier_sigma, quiet):
    """Single-point positions and Doppler velocities of every epoch of OBS (RINEX 2.11/3.x observations,
    gzip or Hatanaka compressed, or a u-blox UBX log) with the broadcast ephemerides of NAV, written as a
    docs/formats.md GNSS CSV that `sins navigate --gnss` fuses as it is.

    \b
    Example:
      sins gnss spp slac1350.20o --nav brdc1350.20n -o gnss.csv
      sins gnss spp f9p.ubx --tdcp --time posix-gpst -o gnss.csv
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
    tdcp_note = ""
    if tdcp:
        vel, std_v, tdcp_note = _tdcp_velocity(res, nav, opts, carrier_sigma, vel, std_v, obs_path)
    t = res.solution_time()
    if time_base == "tow":
        t = t - np.floor(res.time / SECONDS_PER_WEEK) * SECONDS_PER_WEEK
    elif time_base in ("utc", "posix-gpst"):
        from ..io.timebase import from_gps  # the command's modules load when it runs: --help stays light
        t = from_gps(t, "utc" if time_base == "utc" else "gps")
    t = t + time_offset
    data = {"time": t[ok], "lat": lat[ok], "lon": lon[ok], "height": h[ok]}
    vel_ok = res.vel_ok if not tdcp else np.isfinite(vel).all(axis=1)
    with_vel = bool(vel_ok[ok].all())
    if with_vel:
        for i, c in enumerate(("vel_e", "vel_n", "vel_u")):
            data[c] = vel[ok, i]
    for i, c in enumerate(("std_e", "std_n", "std_u")):
        data[c] = std[ok, i]
    if with_vel:
        for i, c in enumerate(("std_vel_e", "std_vel_n", "std_vel_u")):
            data[c] = std_v[ok, i]
    elif vel_ok[ok].any():
        log.warning("%s: %d of %d fixes have no %s velocity (fewer than 4 %s): the velocity columns are left out",
                    obs_path, int((~vel_ok[ok]).sum()), int(ok.sum()), "TDCP or Doppler" if tdcp else "Doppler",
                    "continuous carriers or Dopplers" if tdcp else "Doppler measurements")
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
                   f"{'; Doppler velocity on every fix' if with_vel and not tdcp else ''}{tdcp_note}; times: "
                   f"{TIME_BASES[time_base]} (--time {time_base})"
                   f"{f' plus {time_offset:g} s' if time_offset else ''} -> {output}", err=True)


def _tdcp_velocity(res, nav, opts, carrier_sigma, vel, std_v, obs_path):
    """The fixes' velocities (ENU, m/s) and sigmas from TDCP (:func:`sinscli.gnss.tdcp.tdcp_velocity`) where it
    has one, the Doppler's elsewhere (NaN where neither); and the summary's note."""
    import numpy as np  # the command's modules load when it runs: --help stays light
    from ..gnss.tdcp import tdcp_velocity  # the command's modules load when it runs
    from ..nav.earth import ecef_to_lla, enu_rotation  # the command's modules load when it runs
    tv = tdcp_velocity(res, nav, opts, carrier_sigma=carrier_sigma)
    if tv["carriers"] == 0:
        log.warning("%s: no carrier-phase observation of the satellites used: --tdcp off, Doppler velocities",
                    obs_path)
        return vel, std_v, "; --tdcp: no carrier phase"
    lat, lon, _ = ecef_to_lla(res.pos)
    rot = enu_rotation(lat, lon)
    have = tv["kind"] > 0
    vel = np.where(res.vel_ok[:, None], vel, np.nan)
    std_v = np.where(res.vel_ok[:, None], std_v, np.nan)
    v_enu = np.einsum("eij,ej->ei", rot, np.nan_to_num(tv["vel"]))
    c_enu = rot @ np.nan_to_num(tv["cov"]) @ np.swapaxes(rot, 1, 2)
    vel[have] = v_enu[have]
    std_v[have] = np.sqrt(np.einsum("eii->ei", c_enu))[have]
    ok = res.fix
    slips = ", ".join(f"{k} {v}" for k, v in tv["slips"].items())
    return vel, std_v, (f"; TDCP velocity on {int((have & ok).sum())} of {int(ok.sum())} fixes "
                        f"({int(((tv['kind'] == 2) & ok).sum())} central differences), {tv['pairs']} carrier "
                        f"pairs, slips left out: {slips}, by the residual test {tv['excluded']}; unit variance "
                        f"{tv['s0sq']:.3g}")
