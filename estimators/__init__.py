"""Estimators of food viscoelasticity (K1, K2, B) and friction (mu) from sensor traces.

Pure numpy/scipy: never imports MuJoCo, so the same code runs on a real robot's logs.
"""
