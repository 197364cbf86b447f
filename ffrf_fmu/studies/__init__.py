"""Studies over a body and its scenes: the sweep layer (sweep.py: where runs go), the runs as data
(task.py), the result store (store.py), parameter studies (study.py), the progress bar."""
