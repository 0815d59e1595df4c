"""bench_ccsds"""
