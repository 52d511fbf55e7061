"""Robot links: the simulated robot, a Mitsubishi MELFA controller, a KUKA REST bridge (and
its controller side, `kuka_bridge/`), a Universal Robots controller (RTDE + URScript +
primary interface) and an ABB IRC5 or OmniCore over Robot Web Services 1.0 / 2.0.

Everything here implements `assistant.links.link.RobotLink`; `settings.make_link` builds the
one a session chose, `checklist` is the pre-flight check, `wirelog` the record of the
traffic. `assistant/emulators/` holds TCP/HTTP peers driven by our kinematic model, in each
controller's factory state, so the real client code is tested against a real socket (and
``cellteach emulate`` serves them). Must not import viser, workflow or web.
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
