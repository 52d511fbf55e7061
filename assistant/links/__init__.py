"""Robot links: the simulated robot, a Mitsubishi MELFA controller, a KUKA REST bridge, a
Universal Robots controller (RTDE + URScript) and an ABB IRC5 over Robot Web Services.

Everything here implements `assistant.links.link.RobotLink`; `settings.make_link` builds the
one a session chose. `emulators/` holds TCP/HTTP peers driven by our kinematic model so the
real client code is tested against a real socket. Must not import viser, workflow or web.
Metres and radians inside; millimetres and degrees only in the wire formats.
"""

from assistant.links.errors import ControllerRefused, ProtocolError
from assistant.links.settings import LinkSettings, LinkSettingsError, make_link
from assistant.links.timing import RealClock, VirtualClock

__all__ = [
    "ControllerRefused",
    "LinkSettings",
    "LinkSettingsError",
    "ProtocolError",
    "RealClock",
    "VirtualClock",
    "make_link",
]
