"""bench_models"""
