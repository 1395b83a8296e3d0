"""rovermarl: cooperative co-evolution (CC-(1+1)-ES with fixed or adaptive k) for multi-rover teams."""

__all__ = ["Rollout", "World", "make_world"]
__version__ = "0.1.0"


def __getattr__(name: str):
    """``rovermarl.make_world`` and friends, imported on first use: ``import rovermarl.train`` stays light until its
    signal handlers are in place."""
    if name in __all__:
        from rovermarl import env
        return getattr(env, name)
    raise AttributeError(f"module 'rovermarl' has no attribute {name!r}")
