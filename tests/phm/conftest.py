"""Fixtures for the PHM feature/detection tests.

* ``synth_actuator``: a factory of synthetic 800 Hz actuator signals built from the d-q motor
  equations (no simulator needed) with optional faults, for fast unit tests.
* ``campaigns``: quick design and verification campaigns generated once per session with the
  simulator's CLI (fixed seeds) into a temporary directory; the slow tests skip when the
  simulator is not installed.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

FS = 800.0
P = 4
R = 1.86
L = 3.72e-3
PSI = 0.061
LEAD = 0.005
RS = LEAD / (2 * np.pi)


def make_actuator(
    *,
    seconds: float = 60.0,
    seed: int = 0,
    psi_scale: float = 1.0,
    se_amp: float = 0.0,
    tts_i0: float = 0.0,
    bdo: float = 0.0,
    backlash_m: float = 0.0,
    backlash_follows: str = "torque",
    hold_eta: float = 0.9,
    eta_d: float = 0.9,
    eta_b: float = 0.89,
    drag_nm: float = 0.0,
    load_gradient: float = 4.0e4,
    load_bias_n: float = 0.0,
    r_ohm: float = R,
    noise_a: float = 0.02,
    noise_v: float = 0.2,
    noise_x: float = 2e-6,
    move_time_scale: float = 1.0,
) -> dict[str, np.ndarray]:
    """Synthetic EMA signals from the d-q equations (i_d = 0 control, ideal current loop).

    The rod follows a sequence of smooth moves and holds; motor torque = J alpha + load
    torque; a hold carries ``hold_eta`` x the load torque (back-driving efficiency).
    Moving against the load the motor torque is ``r F / eta_d``, moving with it ``r F eta_b``,
    plus a Coulomb drag ``drag_nm`` opposing the motion.
    ``psi_scale`` < 1 is magnet degradation, ``se_amp`` modulates the flux with the mechanical
    angle, ``tts_i0`` adds a common-node current proportional to the phase-a current,
    ``bdo`` clips the positive half of phase a's voltage, ``backlash_m`` adds a dead zone
    between shaft and rod: the rod sits on the flank the torque presses, or with
    ``backlash_follows="motion"`` on the side of the last motion (a damping-dominated link).
    ``move_time_scale`` stretches every move's duration (slower moves, the same targets).
    """
    rng = np.random.default_rng(seed)
    n = int(seconds * FS)
    t = np.arange(n) / FS
    # position profile: random targets, raised-cosine moves of 0.6-1.5 s, holds of 0.5-2 s
    x_cmd = np.zeros(n)
    k, pos = 0, 0.0
    while k < n:
        target = rng.uniform(-0.02, 0.02)
        m = int(rng.uniform(0.6, 1.5) * move_time_scale * FS)
        h = int(rng.uniform(0.5, 2.0) * FS)
        s = 0.5 - 0.5 * np.cos(np.pi * np.arange(m) / m)
        seg = np.r_[pos + (target - pos) * s, np.full(h, target)]
        x_cmd[k : k + seg.size] = seg[: n - k]
        k += seg.size
        pos = target
    theta = x_cmd / RS
    w = np.gradient(theta, 1 / FS)
    acc = np.gradient(w, 1 / FS)
    load = load_gradient * x_cmd + load_bias_n
    moving = np.abs(w) > 0.05
    against = np.sign(w) == np.sign(load)  # moving away from neutral pushes against the load
    t_move = np.where(against, RS * load / eta_d, RS * load * eta_b) + drag_nm * np.sign(w)
    t_load = np.where(moving, t_move, hold_eta * RS * load)
    torque = 1e-4 * acc + t_load
    psi_th = PSI * psi_scale * (1.0 + se_amp * np.cos(theta))
    iq = torque / (1.5 * P * psi_th)
    th_e = P * theta
    diq = np.gradient(iq, 1 / FS)
    we = P * w
    vd = -we * L * iq
    vq = r_ohm * iq + L * diq + we * psi_th
    c, s_ = np.cos(th_e), np.sin(th_e)
    i_al, i_be = -iq * s_, iq * c
    v_al, v_be = vd * c - vq * s_, vd * s_ + vq * c
    ia = i_al
    ib = -0.5 * i_al + np.sqrt(3) / 2 * i_be
    ic = -0.5 * i_al - np.sqrt(3) / 2 * i_be
    va = v_al
    vb = -0.5 * v_al + np.sqrt(3) / 2 * v_be
    vc = -0.5 * v_al - np.sqrt(3) / 2 * v_be
    if tts_i0:
        i0 = tts_i0 * ia
        ia, ib, ic = ia + i0 / 3, ib + i0 / 3, ic + i0 / 3
    if bdo:
        va = np.where(va > 0, va * (1 - bdo), va)
    x_rod = x_cmd.copy()
    if backlash_m:
        # the rod sits half the gap behind the screw on the flank the load torque presses
        # (the side is kept while the torque is too small to tell)
        if backlash_follows == "torque":
            sgn = np.sign(torque)
            sgn[np.abs(torque) < 0.05] = 0
        else:  # a link whose force follows the motion (damping-dominated, rod-end-like)
            sgn = np.sign(w)
            sgn[~moving] = 0
        idx = np.maximum.accumulate(np.where(sgn != 0, np.arange(n), 0))
        side = sgn[idx]
        side[side == 0] = 1
        x_rod = x_cmd - side * backlash_m / 2
    out = {
        "ia": ia + noise_a * rng.standard_normal(n),
        "ib": ib + noise_a * rng.standard_normal(n),
        "ic": ic + noise_a * rng.standard_normal(n),
        "va": va + noise_v * rng.standard_normal(n),
        "vb": vb + noise_v * rng.standard_normal(n),
        "vc": vc + noise_v * rng.standard_normal(n),
        "theta": theta,
        "x": x_rod + noise_x * rng.standard_normal(n),
        "t": t,
    }
    return out


@pytest.fixture
def synth_actuator() -> Callable[..., dict[str, np.ndarray]]:
    return make_actuator


# --------------------------------------------------------------------------------------------
# simulated campaigns (generated once per session under the shared ``campaign_root`` of
# tests/conftest.py; PHM_CAMPAIGN_DIR reuses existing ones)
# --------------------------------------------------------------------------------------------

DESIGN_SEED = 1
VERIFICATION_SEED = 2


def _sim_worker_exe() -> str | None:
    exe = Path(os.environ.get("VIRTUAL_ENV", Path(__file__).resolve().parents[2] / ".venv"))
    cand = exe / "bin" / "sim-worker"
    if cand.exists():
        return str(cand)
    return shutil.which("sim-worker")


def _campaign(kind: str, seed: int, root: Path, render_every: int | None = None) -> Path:
    """``root/<kind>_<seed>`` (``..._every<N>`` with ``render_every``), generated unless
    present. ``PHM_DESIGN_DIR`` / ``PHM_VERIFICATION_DIR`` / ``PHM_VERIFICATION_EVERY5_DIR``
    point straight at existing campaign directories (e.g. /tmp/cq2)."""
    suffix = f"_every{render_every}" if render_every else ""
    direct = os.environ.get(f"PHM_{kind.upper()}{suffix.upper()}_DIR")
    if direct and (Path(direct) / "manifest.json").exists():
        return Path(direct)
    out = root / f"{kind}_{seed}{suffix}"
    if (out / "manifest.json").exists():
        return out
    try:
        import sim_worker.cli  # noqa: F401
    except ImportError:
        pytest.skip("the simulator (sim_worker.cli) is not available")
    exe = _sim_worker_exe()
    if exe is None:
        pytest.skip("sim-worker console script not installed")
    subprocess.run(
        [
            exe,
            "campaign",
            "--kind",
            kind,
            "--out",
            str(out),
            "--seed",
            str(seed),
            "--scale",
            "quick",
            *(["--render-every", str(render_every)] if render_every else []),
        ],
        check=True,
        capture_output=True,
        timeout=900,
    )
    return out


@pytest.fixture(scope="session")
def design_campaign(campaign_root: Path):
    from server.campaigns import load_campaign

    return load_campaign(_campaign("design", DESIGN_SEED, campaign_root), jobs=2)


@pytest.fixture(scope="session")
def verification_campaign(campaign_root: Path):
    from server.campaigns import load_campaign

    return load_campaign(_campaign("verification", VERIFICATION_SEED, campaign_root), jobs=2)


@pytest.fixture(scope="session")
def dense_verification_campaign(campaign_root: Path):
    """The verification campaign with every 5th flight of a fault-to-failure run rendered
    (the quick one renders every 20th: three flights of evidence are then 60 flights of a
    170-450-flight life, while an aircraft in service downloads every flight)."""
    from server.campaigns import load_campaign

    return load_campaign(_campaign("verification", VERIFICATION_SEED, campaign_root,
                                   render_every=5), jobs=2)


@pytest.fixture(scope="session")
def detection_model(design_campaign):
    from server.phm.detection_model import fit_detection

    return fit_detection(design_campaign)


@pytest.fixture(scope="session")
def verification_outcomes(detection_model, verification_campaign):
    from server.evaluation.evaluate_detection import evaluate

    return evaluate(detection_model, verification_campaign)


@pytest.fixture(scope="session")
def dense_verification_outcomes(detection_model, dense_verification_campaign):
    from server.evaluation.evaluate_detection import evaluate

    return evaluate(detection_model, dense_verification_campaign)
