"""Shared by the scripts/validate_*.py scripts: run bootsurf, print markdown tables."""
import subprocess
import sys


def run(args):
    """Runs a command; on failure prints it with its stderr and exits 1."""
    r = subprocess.run(args, capture_output=True, text=True)
    if r.returncode != 0:
        sys.stderr.write("failed: %s\n%s" % (" ".join(args), r.stderr))
        sys.exit(1)
    return r.stdout


def row(*cells):
    print("| " + " | ".join(str(c) for c in cells) + " |")


def header(*cells):
    row(*cells)
    row(*(["---"] * len(cells)))
