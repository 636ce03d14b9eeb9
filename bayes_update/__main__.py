"""``python -m bayes_update``: the command line (:mod:`bayes_update.reports.cli`)."""
import sys

from bayes_update.reports.cli import main

sys.exit(main())
