"""Localhost peers for the links, driven by our kinematic model: a MELFA CR controller
(TCP text protocol + data link) and the 002 KUKA REST bridge (HTTP). They move in time,
answer in the real formats, own hidden obstacles, and produce faults on request
(`faults.Faults`). Test and demo tools; the product never needs them at run time.
"""
