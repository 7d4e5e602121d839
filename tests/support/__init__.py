"""Shared test fixtures: what is expensive to make (a simulated campaign, a loop closure) is made
once per test session and shared by every test that asks for the same inputs."""
