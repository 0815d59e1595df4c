"""The published studies, one package each (scenario, paper numbers and claims, metrics, report section)."""
