"""The rigorous bundle: the sparse adjustment (:mod:`.adjust`), its data
snooping in one frame (:mod:`.snooping`), and the refinement of a strip-method
result in a Cartesian frame (:mod:`.refine`).
"""
