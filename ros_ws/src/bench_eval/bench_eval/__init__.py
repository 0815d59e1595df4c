"""bench_eval"""
