"""Marker pointer: cameras, HSV colour calibration, blob detection, tracking, 3-D position.

Never imports viser; the web layer shows what the tracker produces.
"""
