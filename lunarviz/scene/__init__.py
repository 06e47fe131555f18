"""The resolved scene: a run's every option, checked and typed, and the inputs it gives each layer
below (:class:`~lunarviz.scene.resolved.ResolvedScene`)."""

from lunarviz.scene.resolved import ResolvedScene

__all__ = ["ResolvedScene"]
