"""Throughput benchmark (same as `mate bench`): env-steps/s of the single env and the batched core.

    python benchmarks/throughput.py [--seconds 2] [--json benchmarks/results/throughput.json]
"""

import sys

from mate.cli.main import main

if __name__ == '__main__':
    args = sys.argv[1:]
    if '--json' not in args:
        args += ['--json', 'benchmarks/results/throughput.json']
    sys.exit(main(['bench', *args]))
