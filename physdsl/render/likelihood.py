"""The likelihood of an image observation: the scene rendered by its camera at the observed
frame times and compared with the frames (``observe.image.image_log_likelihood``)."""
from __future__ import annotations

import jax.numpy as jnp

from ..errors import DataError
from ..expr import evaluate
from ..observe.image import image_log_likelihood, observed_frames
from .scene import render_frames


def scene_image_log_likelihood(model, obs, rollout, values, levels: int = 3, softness=0.5):
    """Log-likelihood of an image Observation of ``model.scene`` given a rollout: the scene's
    camera ``obs.target`` renders the bodies at the (subsampled) frame times, compared with
    the frames by ``image_log_likelihood`` under the observation's noise model."""
    times, frames = observed_frames(obs)
    cam = next((c for c in model.scene.cameras if c.name == obs.target), None)
    if cam is not None and frames.shape[1:3] != (cam.size[1], cam.size[0]):
        raise DataError(f"frames are {frames.shape[2]}x{frames.shape[1]} pixels but camera "
                        f"'{cam.name}' is {cam.size[0]}x{cam.size[1]}", obs.frames[0],
                        hint="set the camera's size to the frames' size")
    images = render_frames(model.scene, model.simulator, rollout, values, obs.target, times,
                           softness)
    sigma = evaluate(obs.noise.scale, values)
    df = evaluate(obs.noise.df, values) if obs.noise.df is not None else 4.0
    return image_log_likelihood(images, jnp.asarray(frames), sigma, levels=levels,
                                kind=obs.noise.kind, df=df)
