"""The simulated suit: plant physics, mannequin bench, virtual participants and batch simulation."""
