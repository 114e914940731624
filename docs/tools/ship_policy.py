"""Ship a trained policy as `mate/pretrained/NAME.pt` (`pretrained:NAME`): the policy file of a run (`best-eval.pt`,
`final.pt`, ...), set to act deterministically (argmax, how shipped policies are scored), with a note saying where
it comes from.

    python docs/tools/ship_policy.py runs/pretrain/mappo-target-4v8-0/best-eval.pt mappo-target-4v8-0 --note '...'
"""

from __future__ import annotations

import argparse
import sys

from mate.policies.checkpoint import load_checkpoint, read_spec, save_checkpoint
from mate.policies.policy import PRETRAINED_DIR


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument('policy', help='a policy file of a run (best-eval.pt, best.pt, final.pt)')
    parser.add_argument('name', help='the shipped name: mate/pretrained/NAME.pt')
    parser.add_argument('--note', required=True, help='how it was trained and what it scores')
    args = parser.parse_args(argv)
    data = load_checkpoint(args.policy)
    spec = read_spec(data, args.policy).replace(deterministic=True)
    shipped = dict(spec=spec.to_dict(), algo=data.get('algo', spec.algo), actor=data['actor'],
                   config=data.get('config', {}), env_steps=int(data.get('env_steps', 0)), note=args.note)
    path = save_checkpoint(PRETRAINED_DIR / f'{args.name}.pt', shipped)
    print(f'{path}: {spec.team} policy for {spec.env_id}, {shipped["env_steps"]:,} decision steps')
    return 0


if __name__ == '__main__':
    sys.exit(main())
