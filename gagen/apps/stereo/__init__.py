"""Stereo symmetry-line pose estimation in CGA [SMC IV]: a calibrated camera pair, generated geometry
kernels (image lines to the object's 3D symmetry axis), an OpenCV front end, a synthetic scene with
ground truth, and the estimate as the sliding-mode controller's reference."""
