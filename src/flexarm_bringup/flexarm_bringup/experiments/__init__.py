"""The research harness: the demo and the benchmark (Tables 9 and 10 through a running graph)
and the sensitivity study (Tables 7 and 8)."""
