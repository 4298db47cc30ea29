"""The ground stage: the strip model to the control, either every model at once
(:mod:`.models`, R4 3 for one strip) or the strip as one body with J's
similarity and deformation polynomials (:mod:`.polynomials` with its passes
in :mod:`.passes`); :mod:`.common` holds what both constructions share.
"""
