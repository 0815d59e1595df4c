"""The CCSDS commands: ``bench_export`` (a bag to OEM and TDM files) and ``bench_import_tdm`` (a TDM, with an optional
OEM reference, replayed into the bench's estimators). Each module holds ``main(argv) -> int`` and the console
script's ``command()``; ``scripts/export.py`` and ``scripts/import_tdm.py`` run the same ``main``."""
