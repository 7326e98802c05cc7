"""Evaluation: CLEAR MOT and identity metrics on the ground plane, scenario runner."""
