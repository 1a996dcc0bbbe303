"""Generator B: a second trace generator for discovery, written from the trace format and the
physics notes only (it imports nothing of the `tether` package). See docs/generator_b.md.

    from bench.generator_b import suite, generate, write_suite
    specs = suite(n=48, seed=7)       # seed 2026 is the held-out draw: never look at it for tuning
"""

from .draw import suite
from .experiments import generate, GenerationError
from .traceio import read_trace, write_trace
from .cli import write_suite

__all__ = ["suite", "generate", "write_suite", "read_trace", "write_trace", "GenerationError"]
