"""Strip formation: relative orientation of every pair by the y-parallax
equation (:mod:`.relative`), model formation and scale transfer on the tie
points (:mod:`.scaling`), chaining into one strip model (:mod:`.chaining`),
and densification (models on every k-th photo, the others resected;
:mod:`.densify`).
"""
