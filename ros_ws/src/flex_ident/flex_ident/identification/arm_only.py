"""Identification of an arm-only experiment (no object): the closed loop in the torque domain
(``flex_ident.diagnosis.arm_torque``), its report (CONTRACTS.md section 3 fields with torque errors) and plots."""
from __future__ import annotations

import time
from pathlib import Path

import numpy as np

from ..diagnosis.arm_torque import ArmDiagnosisError, PinocchioArm, choose_window, diagnose_arm
from .report import write_report


def identify_arm_only(bag_path, experiment, out_dir, validation_fraction=0.3, plots=True, progress=None) -> dict:
    from robot_bridge.bagio.contract import read_joint_recording

    t0 = time.monotonic()
    arm_spec = experiment.arm
    joints = list(arm_spec.joints)
    if not Path(bag_path).exists():
        raise ArmDiagnosisError(f'bag {bag_path} does not exist')
    rec = read_joint_recording(str(bag_path), joints=joints, window=experiment.identify.window_s,
                               require_effort=True)
    arm = PinocchioArm(arm_spec.urdf_path, joints, arm_spec.base_link, arm_spec.gravity_mps2)
    problems = arm.inertia_problems()
    fatal = [p for p in problems if 'mass' in p or 'positive definite' in p]
    if fatal:
        raise ArmDiagnosisError(f'URDF {arm_spec.urdf_path} has inertial data no rigid body can have: '
                                + '; '.join(fatal))
    warnings = []
    if problems:
        warnings.append('the URDF\'s inertial data is not physically valid for link(s): ' + '; '.join(problems)
                        + ' (diagnosed anyway; the inertial candidate can absorb it)')
    sig = choose_window(rec.t_s, rec.position, rec.effort, joints, arm, validation_fraction)
    found = diagnose_arm(sig, arm, validation_fraction=validation_fraction, progress=progress)
    pred, residual, parts = found.pop('_prediction'), found.pop('_residual'), found.pop('_contributions')
    if found['constant_effort_joints']:
        warnings.append(f'constant effort (no torque sensor?) on {found["constant_effort_joints"]}: left out')
    if found['inertial_data_wrong']:
        warnings.append("the URDF's inertial parameters (masses, centres of mass, inertias) are wrong: fitting their "
                        'base parameters was the largest improvement on data never fitted'
                        if found['effects_added'][0]['key'] == 'inertial' else
                        "the URDF's inertial parameters need correcting (an inertial-parameter fit lowered the "
                        'validation error)')
    before, after = found['error_before']['torque_rms_nm'], found['error_after']['torque_rms_nm']
    report = {
        'model': 'arm only: URDF rigid-body dynamics (Pinocchio RNEA + declared damping), torque domain',
        'parameters': {}, 'parameter_std': {},
        'error_before': found['error_before'], 'error_after': found['error_after'],
        'effects_added': found['effects_added'],
        'improvement_factor': before / after if after > 0 else None,
        'iterations': len(found['rounds']),
        'warnings': warnings,
        'diagnosis': {'rounds': found['rounds'], 'base_parameters': found['base_parameters'],
                      'torque_noise_rms_nm': found['torque_noise_rms_nm'],
                      'validation_fraction': validation_fraction, 'samples': found['samples'],
                      'differentiation': f'Savitzky-Golay, cubic, {sig.window_samples} samples '
                                         f'({1000 * sig.window_samples * sig.dt:.0f} ms), chosen from 25-200 ms by '
                                         'the smallest nominal residual on the fitted part'},
        'data': {'bag': str(bag_path), 'joints': joints, 'duration_s': float(sig.t_s[-1] - sig.t_s[0]),
                 'sample_period_s': sig.dt},
    }
    out = Path(out_dir)
    if plots:
        out.mkdir(parents=True, exist_ok=True)
        report['plots'] = [p.name for p in _plots(out, sig, residual, pred, parts, found, validation_fraction)]
    report['wall_time_s'] = time.monotonic() - t0
    write_report(out, report)
    return report


def _plots(out, sig, residual, pred, parts, found, validation_fraction):
    import matplotlib
    matplotlib.use('Agg')
    import matplotlib.pyplot as plt
    names = sig.names
    n = len(names)
    N = len(sig.t_s)
    n_val = int(round(validation_fraction * N))
    paths = [out / 'residual_per_joint.png', out / 'friction_signature.png']
    fig, axes = plt.subplots(n, 1, figsize=(10, 1.6 * n + 1), sharex=True)
    for j, ax in enumerate(np.atleast_1d(axes)):
        ax.plot(sig.t_s, residual[:, j], color='0.6', lw=0.6, label='nominal model')
        ax.plot(sig.t_s, residual[:, j] - pred[:, j], color='tab:red', lw=0.6, label='after the closed loop')
        ax.axvspan(sig.t_s[N - n_val], sig.t_s[-1], color='tab:blue', alpha=0.07)
        b = found['error_before']['per_joint_nm'][names[j]]
        a = found['error_after']['per_joint_nm'][names[j]]
        ax.set_ylabel(f'{names[j]}\n[N m]', fontsize=7)
        ax.text(0.01, 0.85, f'validation RMS {b:.3f} -> {a:.3f} N m', transform=ax.transAxes, fontsize=7)
        ax.grid(alpha=0.3)
    np.atleast_1d(axes)[0].legend(fontsize=7, loc='upper right')
    np.atleast_1d(axes)[-1].set_xlabel('time [s] (shaded: validation part, never fitted)')
    fig.suptitle('Torque residual (measured - model) per joint', fontsize=10)
    fig.tight_layout()
    fig.savefig(paths[0], dpi=100)
    plt.close(fig)
    cols = min(n, 4)
    rows = int(np.ceil(n / cols))
    fig, axes = plt.subplots(rows, cols, figsize=(3.2 * cols, 2.8 * rows), squeeze=False)
    step = max(1, N // 3000)
    for j in range(rows * cols):
        ax = axes.flat[j]
        if j >= n:
            ax.axis('off')
            continue
        v = sig.qd[::step, j]
        friction = sum((parts[k][::step, j] for k in parts if 'viscous' in k or 'coulomb' in k), np.zeros(len(v)))
        others = pred[::step, j] - friction       # every other fitted effect removed: what friction must explain
        ax.plot(v, residual[::step, j] - others, '.', ms=1, color='0.5', label='residual (other effects removed)')
        order = np.argsort(v)
        ax.plot(v[order], friction[order], '-', color='tab:red', lw=1.2, label='fitted friction')
        ax.set_title(names[j], fontsize=8)
        ax.set_xlabel('velocity [rad/s]', fontsize=7)
        ax.set_ylabel('torque [N m]', fontsize=7)
        ax.grid(alpha=0.3)
    axes.flat[0].legend(fontsize=6)
    fig.suptitle('Friction signature: residual against joint velocity', fontsize=10)
    fig.tight_layout()
    fig.savefig(paths[1], dpi=100)
    plt.close(fig)
    return paths
