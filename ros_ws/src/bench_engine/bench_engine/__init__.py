"""bench_engine"""
