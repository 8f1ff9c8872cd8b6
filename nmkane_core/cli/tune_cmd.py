"""``nmkane tune`` (placeholder)."""
from .command import Command

COMMAND = Command("tune", "choose Γ (Γ1, Γ2)", lambda p: None, lambda a: 0)
