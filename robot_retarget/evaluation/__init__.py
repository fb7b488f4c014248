"""Retargeting evaluation: numpy metric functions (reusable for robot-side evaluation) and the
``eval`` runner that applies them to a model on unseen subjects.

The metric modules (skeleton_measures, metrics, foot_contact, noise) import numpy only; the
runner imports the network code.
"""
