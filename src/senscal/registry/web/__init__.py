"""Read-only web view of the sensor registry (``senscal registry serve``).

Server-rendered pages (Flask with Jinja2 templates) of the sensors and
reference standards with their due dates, each sensor's history plot and
drift, every calibration with its certificate files, and the hash-chain
status.  The database is opened read-only (:mod:`.readonly`) and the
application has no endpoint that writes; nothing on a page is fetched from
the network.

Examples
--------
>>> from senscal.registry.web import ViewOptions, create_app, open_read_only
>>> app = create_app(open_read_only("lab.sqlite"), ViewOptions(tolerance=0.01))   # doctest: +SKIP
>>> app.test_client().get("/").status_code                                        # doctest: +SKIP
200
"""

from senscal.registry.web.app import CERTIFICATE_TYPES, LOCAL_HOSTS, ViewOptions, certificate_files, create_app
from senscal.registry.web.readonly import ReadOnlyRegistry, open_read_only
from senscal.registry.web.server import is_loopback, make_server

__all__ = ["ViewOptions", "create_app", "open_read_only", "ReadOnlyRegistry", "make_server", "is_loopback",
           "certificate_files", "CERTIFICATE_TYPES", "LOCAL_HOSTS"]
