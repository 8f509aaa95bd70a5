"""The ACL controller emulator: ``server.AclEmulator`` and its parts (``selfcal/hw/__init__.py``
lists them)."""
