"""From runs and committed records to the paper's numbers: reports, aggregates over seeds, claims, tables, the campaign drivers (compare, campaign) and the measurement studies (`studies/`)."""
