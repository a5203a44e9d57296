"""From runs and committed records to the paper's numbers: reports, aggregates over seeds, claims, tables and the studies (compare, campaign, converge, latent)."""
