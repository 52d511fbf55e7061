"""Localhost peers for the links, driven by our kinematic model, each in its controller's
factory state: a MELFA CR controller (TCP text protocol + data link), the 002 KUKA REST
bridge (HTTP, RV-2AJ) and a KUKA KR C4 running the shipped bridge's own KRL program
(`kuka_krc_emulator`, KR 6 R900 sixx), a Universal Robots e-Series (RTDE v2, primary and
secondary interfaces with a URScript subset, dashboard; Local control until switched) and an
ABB IRC5 / OmniCore speaking RWS 1.0 / 2.0 (digest or Basic over TLS, mastership,
subscriptions; RAPID modules run by `abb_rapid_program`). They move in time, answer in the
real formats, own hidden obstacles, and produce faults on request (`faults.Faults`).
`launch.start` starts one on the vendor's usual ports (``cellteach emulate``). A room of
their own above the links: demo and test peers the product's links never need.

May import: links (the shared wire formats and arm model), robots, collision, transforms.
"""
