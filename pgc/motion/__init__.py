"""Captured motion clips: Acclaim ASF/AMC and BVH readers, a BVH writer, forward kinematics, retargeting onto
a body rig, resampling to the simulation rate and the blend from the capture pose (see docs/simulation.md)."""
