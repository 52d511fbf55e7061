"""Localhost peers for the links, driven by our kinematic model: a MELFA CR controller
(TCP text protocol + data link), the 002 KUKA REST bridge (HTTP), a Universal Robots
controller (RTDE v2, secondary interface with a URScript subset, dashboard) and an ABB IRC5
speaking RWS 1.0 (HTTP, digest login, mastership; RAPID modules run by
`abb_rapid_program`). They move in time, answer in the real formats, own hidden obstacles,
and produce faults on request (`faults.Faults`). Test and demo tools; the product never
needs them at run time.
"""
