"""Geometry of photos and points, free of any project: rotation parametrisations
(:mod:`.rotation`: Cardan alpha-omega-chi, Schut a-b-c, omega-phi-kappa), the
collinearity equations (:mod:`.collinearity`), intersection of rays
(:mod:`.intersection`), the 3D similarity (:mod:`.similarity`), the
deformation polynomials with the straight-line condition (:mod:`.deformation`),
the simultaneous transformation of units (:mod:`.simultaneous`), and the
precision of rays and centres (:mod:`.precision`).
"""
