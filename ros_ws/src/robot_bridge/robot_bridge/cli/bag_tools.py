"""bag-tools: inspect, import and recover rosbag2 joint logs.

  bag-tools info BAG [--json]                       topics, counts, duration, rate, joint names
  bag-tools import-csv CSV --out BAG (--preset P | --map mapping.yaml) [--storage mcap|sqlite3] [--stamp0 NS]
  bag-tools reindex BAG                             rebuild a bag whose writer was killed
"""
from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from robot_bridge.bagio.contract import JOINT_STATE_TYPE, JOINT_STATES, write_joint_recording
from robot_bridge.bagio.csv_import import PRESETS, import_csv, load_mapping
from robot_bridge.bagio.raw import STORAGES, deserialize, iter_raw_messages
from robot_bridge.bagio.reindex import reindex_bag


def bag_info(bag: str) -> dict:
    """Per topic: type, count, duration (s), mean rate (Hz) of the bag's receive times; for /joint_states also
    the span and rate of the header stamps (what identification uses: a bag recorded from a replay at another
    speed, or with a lagging receiver, differs there); joint names of /joint_states."""
    topics: dict[str, dict] = {}
    stamps: dict[str, list] = {}
    header_ns: list[int] = []
    joint_names: list[str] = []
    for m in iter_raw_messages(bag):
        t = topics.setdefault(m.topic, {'type': m.msgtype, 'count': 0})
        t['count'] += 1
        stamps.setdefault(m.topic, []).append(m.timestamp_ns)
        if m.topic == JOINT_STATES and m.msgtype == JOINT_STATE_TYPE:
            msg = deserialize(m.data, m.msgtype)
            header_ns.append(msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec)
            if not joint_names:
                joint_names = list(msg.name)
    if not topics:
        raise ValueError(f'bag {bag} holds no messages')
    for topic, info in topics.items():
        s = np.asarray(stamps[topic])
        info['duration_s'] = float((s.max() - s.min()) * 1e-9)
        info['rate_hz'] = float((len(s) - 1) / info['duration_s']) if info['duration_s'] > 0 else 0.0
    if header_ns:
        h = np.asarray(header_ns)
        span = float((h.max() - h.min()) * 1e-9)
        topics[JOINT_STATES]['header_duration_s'] = span
        topics[JOINT_STATES]['header_rate_hz'] = float((len(h) - 1) / span) if span > 0 else 0.0
    all_stamps = np.concatenate([np.asarray(v) for v in stamps.values()])
    return {'bag': str(bag), 'duration_s': float((all_stamps.max() - all_stamps.min()) * 1e-9),
            'messages': int(len(all_stamps)), 'topics': topics, 'joint_names': joint_names}


def _info(args):
    info = bag_info(args.bag)
    if args.json:
        print(json.dumps(info, indent=2))
        return 0
    print(f"bag: {info['bag']}\nduration: {info['duration_s']:.3f} s\nmessages: {info['messages']}")
    for topic, t in sorted(info['topics'].items()):
        print(f"  {topic:30s} {t['type']:35s} {t['count']:8d} msgs {t['rate_hz']:9.2f} Hz")
        if 'header_duration_s' in t:
            print(f"  {'':30s} header stamps: {t['header_duration_s']:.3f} s, {t['header_rate_hz']:.2f} Hz")
    if info['joint_names']:
        print(f"joint names: {', '.join(info['joint_names'])}")
    return 0


def _import_csv(args):
    mapping = load_mapping(args.preset, args.map)
    rec, report = import_csv(args.csv, mapping)
    rec.stamp0_ns = args.stamp0
    n = write_joint_recording(args.out, rec, storage=args.storage)
    for note in report.notes:
        print(f'note: {note}')
    duration = float(rec.t_s[-1])
    print(f'wrote {n} /joint_states messages ({len(rec.names)} joints, {duration:.3f} s, '
          f'{(n - 1) / duration if duration > 0 else 0:.1f} Hz) to {args.out}')
    return 0


def _reindex(args):
    n = reindex_bag(args.bag)
    print(f'recovered {n} messages into {args.bag} (original kept as {args.bag.rstrip("/")}.unindexed)')
    return 0


def build_parser():
    parser = argparse.ArgumentParser(prog='bag-tools', description='Inspect, import and recover rosbag2 joint logs.')
    sub = parser.add_subparsers(dest='command', required=True)
    p = sub.add_parser('info', help='topics, counts, duration, rate, joint names')
    p.add_argument('bag')
    p.add_argument('--json', action='store_true', help='print JSON')
    p.set_defaults(func=_info)
    p = sub.add_parser('import-csv', help='turn a CSV joint log into a contract bag')
    p.add_argument('csv')
    p.add_argument('--out', required=True, help='bag directory to create')
    p.add_argument('--preset', choices=None, help=f"one of: {', '.join(sorted(PRESETS))}")
    p.add_argument('--map', help='mapping YAML (see robot_bridge/bagio/csv_import.py)')
    p.add_argument('--storage', default='mcap', choices=sorted(STORAGES))
    p.add_argument('--stamp0', type=int, default=0, help='header stamp of the first sample [ns] (default 0)')
    p.set_defaults(func=_import_csv)
    p = sub.add_parser('reindex', help='rebuild a bag whose writer was killed before closing it')
    p.add_argument('bag')
    p.set_defaults(func=_reindex)
    return parser


def main(argv=None):
    args = build_parser().parse_args(argv)
    try:
        return args.func(args)
    except ValueError as exc:   # BagError, CsvImportError and bad values: one line, no traceback
        print(f'bag-tools {args.command}: error: {exc}', file=sys.stderr)
        return 2


if __name__ == '__main__':
    sys.exit(main())
