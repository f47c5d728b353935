"""Turn a joint log (CSV) into a contract bag: column mapping, units, angle unwrapping, joint names.

A mapping (YAML, or a preset below) says where everything is:

    header: true                       # first row holds column names (false: columns are 0-based indices)
    time: {column: t_s, unit: s}       # unit: s | ms | us | ns | sample (a sample index; needs rate_hz)
    rate_hz: 1000                      # only with unit: sample
    joints: [joint_1, joint_2]         # names written to /joint_states
    position: {columns: [q1, q2], unit: rad, unwrap: false}     # unit: rad | deg
    velocity: {columns: [dq1, dq2], unit: rad/s}                # optional; rad/s | deg/s
    effort: {columns: [tau1, tau2], unit: N m}                  # optional; N m | mN m
    # Optional, for logs split over several files (paths relative to the CSV):
    time_file: time.csv                # time column read from this file instead
    effort_file: input.csv             # effort columns read from this file instead

Rows beyond the shortest of the files are dropped (and reported). Time must increase strictly.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml

from .contract import JointRecording

TIME_UNITS = {'s': 1.0, 'ms': 1e-3, 'us': 1e-6, 'ns': 1e-9}
ANGLE_UNITS = {'rad': 1.0, 'deg': np.pi / 180}
RATE_UNITS = {'rad/s': 1.0, 'deg/s': np.pi / 180}
TORQUE_UNITS = {'N m': 1.0, 'Nm': 1.0, 'N*m': 1.0, 'mN m': 1e-3}


class CsvImportError(ValueError):
    """A CSV or mapping that cannot be imported (message names the problem)."""


def _seven(fmt):
    return [fmt.format(i) for i in range(1, 8)]


PRESETS = {
    # Kinova Gen3 (Chiha 2024): Time is a sample index at 1 kHz; positions wrap, so unwrap.
    'kinova_gen3': {
        'header': True, 'time': {'column': 'Time', 'unit': 'sample'}, 'rate_hz': 1000.0,
        'joints': _seven('joint_{}'),
        'position': {'columns': _seven('Position{}'), 'unit': 'rad', 'unwrap': True},
        'velocity': {'columns': _seven('Velocity{}'), 'unit': 'rad/s'},
        'effort': {'columns': _seven('Torque{}'), 'unit': 'N m'}},
    # Franka Emika Panda (Gaz et al. 2019), the re-packed CSV with seconds.
    'franka_gaz2019': {
        'header': True, 'time': {'column': 't_s', 'unit': 's'},
        'joints': _seven('panda_joint{}'),
        'position': {'columns': _seven('q{}_rad'), 'unit': 'rad'},
        'velocity': {'columns': _seven('dq{}_radps'), 'unit': 'rad/s'},
        'effort': {'columns': _seven('tau{}_Nm'), 'unit': 'N m'}},
    # KUKA LWR4+ (FloBaRoID), the re-packed CSV; joint names as in its URDF.
    'kuka_lwr4': {
        'header': True, 'time': {'column': 't_s', 'unit': 's'},
        'joints': [f'lwr_{i}_joint' for i in range(7)],
        'position': {'columns': _seven('q{}_rad'), 'unit': 'rad'},
        'velocity': {'columns': _seven('dq{}_radps'), 'unit': 'rad/s'},
        'effort': {'columns': _seven('tau{}_Nm'), 'unit': 'N m'}},
    # Schunk 6-DOF (Liu & Althoff 2018): trajectory.csv (q1..6, dq1..6), input.csv (torques), time.csv.
    'schunk_liu2018': {
        'header': False, 'time': {'column': 0, 'unit': 's'}, 'time_file': 'time.csv',
        'joints': [f'schunk_joint_{i}' for i in range(1, 7)],
        'position': {'columns': list(range(6)), 'unit': 'rad'},
        'velocity': {'columns': list(range(6, 12)), 'unit': 'rad/s'},
        'effort': {'columns': list(range(6)), 'unit': 'N m'}, 'effort_file': 'input.csv'},
}


@dataclass
class ImportReport:
    samples: int
    dropped_rows: int = 0
    notes: list[str] = field(default_factory=list)


def load_mapping(preset: str | None = None, mapping_path: str | None = None) -> dict:
    if (preset is None) == (mapping_path is None):
        raise CsvImportError('give exactly one of --preset or --map')
    if preset is not None:
        if preset not in PRESETS:
            raise CsvImportError(f"unknown preset '{preset}'; known presets: {', '.join(sorted(PRESETS))}")
        return PRESETS[preset]
    try:
        mapping = yaml.safe_load(Path(mapping_path).read_text())
    except (OSError, yaml.YAMLError) as exc:
        raise CsvImportError(f'cannot read mapping {mapping_path}: {exc}') from None
    if not isinstance(mapping, dict):
        raise CsvImportError(f'mapping {mapping_path} is not a YAML mapping')
    return mapping


class _Table:
    """A numeric CSV with optional header, addressed by column name or index."""

    def __init__(self, path: Path, header: bool):
        if not path.exists():
            raise CsvImportError(f'{path} does not exist')
        text = path.read_text(errors='replace').strip()
        if not text:
            raise CsvImportError(f'{path} is empty')
        lines = text.splitlines()
        self.path = path
        self.names = [c.strip() for c in lines[0].split(',')] if header else []
        body = lines[1:] if header else lines
        if not body:
            raise CsvImportError(f'{path} has a header but no data rows')
        try:
            self.data = np.loadtxt(body, delimiter=',', ndmin=2)
        except ValueError as exc:
            raise CsvImportError(f'{path}: non-numeric or ragged data ({exc})') from None

    def columns(self, cols) -> np.ndarray:
        idx = []
        for c in cols:
            if isinstance(c, int):
                if not 0 <= c < self.data.shape[1]:
                    raise CsvImportError(f'{self.path} has {self.data.shape[1]} columns; no column index {c}')
                idx.append(c)
            elif c in self.names:
                idx.append(self.names.index(c))
            else:
                raise CsvImportError(f"column '{c}' not in {self.path.name} "
                                   f"(it has {', '.join(self.names[:12])}{' ...' if len(self.names) > 12 else ''})")
        return self.data[:, idx]


def _unit(spec: dict, table: dict, what: str, default: str) -> float:
    unit = spec.get('unit', default)
    if unit not in table:
        raise CsvImportError(f"unknown {what} unit '{unit}'; use one of {', '.join(table)}")
    return table[unit]


def import_csv(csv_path: str | Path, mapping: dict) -> tuple[JointRecording, ImportReport]:
    """Read a joint log described by ``mapping`` into a :class:`JointRecording`."""
    csv_path = Path(csv_path)
    header = bool(mapping.get('header', True))
    main = _Table(csv_path, header)
    joints = mapping.get('joints')
    if not joints or 'position' not in mapping or 'time' not in mapping:
        raise CsvImportError("a mapping needs 'time', 'joints' and 'position'")
    n = len(joints)

    def block(key, units, default, file_key=None):
        spec = mapping.get(key)
        if spec is None:
            return None
        table = _Table(csv_path.parent / mapping[file_key], header) if mapping.get(file_key) else main
        cols = spec.get('columns', [])
        if len(cols) != n:
            raise CsvImportError(f'{key} maps {len(cols)} columns for {n} joints')
        return table.columns(cols) * _unit(spec, units, key, default)

    tspec = mapping['time']
    ttable = _Table(csv_path.parent / mapping['time_file'], header) if mapping.get('time_file') else main
    t = ttable.columns([tspec['column']])[:, 0]
    if tspec.get('unit', 's') == 'sample':
        rate = mapping.get('rate_hz')
        if not rate or rate <= 0:
            raise CsvImportError("time unit 'sample' needs a positive rate_hz")
        t = t / float(rate)
    else:
        t = t * _unit(tspec, TIME_UNITS, 'time', 's')
    pos = block('position', ANGLE_UNITS, 'rad')
    vel = block('velocity', RATE_UNITS, 'rad/s')
    eff = block('effort', TORQUE_UNITS, 'N m', 'effort_file')
    arrays = [a for a in (t, pos, vel, eff) if a is not None]
    k = min(len(a) for a in arrays)
    report = ImportReport(samples=k, dropped_rows=max(len(a) for a in arrays) - k)
    if report.dropped_rows:
        report.notes.append(f'files differ in length: kept the first {k} rows, dropped {report.dropped_rows}')
    t, pos = t[:k], pos[:k]
    vel = None if vel is None else vel[:k]
    eff = None if eff is None else eff[:k]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        raise CsvImportError(f'time does not increase at row {bad[0] + 1} ({t[bad[0]]} -> {t[bad[0] + 1]})')
    if mapping['position'].get('unwrap', False):
        unwrapped = np.unwrap(pos, axis=0)
        jumps = int(np.sum(np.abs(unwrapped - pos) > 1e-9, axis=0).astype(bool).sum())
        report.notes.append(f'unwrapped angles ({jumps} joint(s) had jumps)')
        pos = unwrapped
    rec = JointRecording(t_s=t - t[0], names=list(joints), position=pos, velocity=vel, effort=eff)
    return rec, report
