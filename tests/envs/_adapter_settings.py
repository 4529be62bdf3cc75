"""The settings of the adapter tests (tests/envs/test_adapters.py), which test_rendering.py's Gymnasium tests
share so that their compiled programs are reused."""

LIMIT = 4                 # the adapters' step limit in these tests
NUM_ENVS = 2
# XLA's cheap CPU optimisation level: compiling, not running, is what these short tests spend.
FAST_COMPILE = {"xla_backend_optimization_level": 0, "xla_llvm_disable_expensive_passes": True}
GYM_KW = {"scenario": 1, "wind": False, "max_episode_steps": LIMIT, "compiler_options": FAST_COMPILE}
