"""Monte Carlo campaigns and parameter sweeps of nudyn's FMUs on Dask
(`nudyn-campaign CAMPAIGN.toml --out DIR`, or `run_campaign` in Python)."""

from .runner import CampaignInterrupted, run_campaign
from .spec import CampaignError, load

__all__ = ["CampaignError", "CampaignInterrupted", "load", "run_campaign"]
