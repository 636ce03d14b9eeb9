"""``python -m bayes_update``: the command line (:mod:`bayes_update.cli`)."""

import sys

from bayes_update.cli import main

sys.exit(main())
