"""The paper's experiments as code: each writes JSON (and figures) into an output folder.

Modules
-------
hrtf_figures
    Experiments 1 and 2 of issue 3: the median-plane frequency response with and without
    pinnae (``pinna.json``) and the ILD/IPD of the HRTFs at the paper's six frequencies
    (``hrtf_ild_ipd.json``).
localization
    Experiments 3 and 4: direction estimation in simulation and in a room.
active
    ``eval active``: one head turn against front-back confusion (the scene in
    ``active_scene``, the two-source scenes in ``active_pairs``).
experiment_files
    The output folder, compact JSON and figures of the HRTF experiments.
"""
