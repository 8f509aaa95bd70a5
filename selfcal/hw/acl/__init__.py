"""The ACL controller over a serial line: the text on the wire, errors, replies, parsers, the
link, the guard and ``AclRobot`` (``selfcal/hw/__init__.py`` lists them)."""
