"""The model-gap workflow (`dynid gaps`): where the model and the measurements disagree, which missing physical
effect explains it, and how much of the gap the fix closes on held-out time blocks.

Takes a robot model, a run and optionally a given model; profiles the residual (profile), tries each candidate
effect of dynid.robot.effect_library with a robust Wald test (selection), refits with the named effects
(refit) and builds the augmented model file through dynid.pipeline (workflow → refit). Layer: imports
everything up to the pipeline; report draws its figures.
"""
