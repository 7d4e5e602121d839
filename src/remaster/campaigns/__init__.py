"""Campaigns: the data contract read and checked, controller logs and sensor exports imported,
and simulated campaigns (the twin robots and their sensors)."""
