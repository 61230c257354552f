"""`nudyn-campaign CAMPAIGN.toml --out DIR [--cases N] [--workers N] [--scheduler ADDRESS] [--overwrite]`."""

import sys

from .cli import main

sys.exit(main())
