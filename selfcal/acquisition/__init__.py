"""The acquisition loop and the backends behind the one ``Robot``
interface (simulation, hardware, the simulated robot behind the ACL emulator)."""
