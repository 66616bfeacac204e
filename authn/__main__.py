"""`python -m authn` and the `authn` console script: the command line, in a process tuned first.

`authn.process.tune` raises the collector's threshold before the command line's modules are
imported: their ~80 000 long-lived objects otherwise run ~30 collections (~6 ms of a cold
check) that free nothing.
"""

from __future__ import annotations


def main() -> None:
    """Tune the process, then run the `authn` command (`authn.cli.run`)."""
    from authn.process import tune

    tune()
    from authn.cli import run

    run()


if __name__ == "__main__":
    main()
