"""The per-robot laws of decentralised formations (control layer), one module each.

Every module defines :class:`~quatform.control.local.LocalController` subclasses, which
register in :data:`~quatform.control.local.LOCAL_CONTROLLERS` when imported; this package
imports all of its modules, so a new law is one file here.
"""

from ...registry import import_package_modules

import_package_modules(__name__, __path__)
