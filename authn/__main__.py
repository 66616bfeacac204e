"""`python -m authn` = the `authn` command."""

from authn.cli import run

run()
