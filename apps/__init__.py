"""The applications above the library: they use ``acoustic_sim``, ``tasks`` and ``policies``.

runner
    The ``run`` command: episodes of a task with a policy, a summary and ``episodes.json``.
demo
    The ``demo`` command: one narrated ReverseAlarm episode, a recording and a picture.
eval_tasks
    The ``eval tasks`` command: every task with the scripted, oracle and blind policies.
deaf_search
    The ``deaf-search`` command: the deaf baseline's open-loop parameters searched on design seeds.

``acoustic_sim`` sits below them: apart from its command-line entry (``acoustic_sim/cli*.py``)
nothing in it imports ``apps``, ``tasks`` or ``policies`` (``tests/test_layers.py`` checks).
"""
