"""`python -m lab.results docs`: write the results pages under the folder given (docs/)."""

from __future__ import annotations

import sys
from pathlib import Path

from lab.results import write

if __name__ == "__main__":
    for p in write(Path(sys.argv[1] if len(sys.argv) > 1 else "docs")):
        print(p)
