"""``python -m tire_estimation.evaluation.campaign campaign ...``."""

import os
import sys

from tire_estimation.evaluation.campaign.cli import main

if __name__ == "__main__":
    os.environ.setdefault("PYTHONUNBUFFERED", "1")
    sys.exit(main())
