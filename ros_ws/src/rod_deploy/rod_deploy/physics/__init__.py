"""Rod physics: discrete elastic rods (energies, reference frames, implicit-Euler simulator with table contact and
Coulomb friction, statics and stability)."""
