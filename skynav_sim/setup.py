from setuptools import find_packages, setup

package_name = 'skynav_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='skynav developers',
    maintainer_email='skynav@example.org',
    description='Synthetic UV/green fish-eye recordings with ground truth.',
    license='Apache-2.0',
    entry_points={
        'console_scripts': ['sim_camera = skynav_sim.node:main'],
        'skynav.commands': [
            'sim = skynav_sim.cli',
            'sim.bag = skynav_sim.cli.bag',
            'sim.follow = skynav_sim.cli.follow',
            'sim.home = skynav_sim.cli.home',
            'sim.preview = skynav_sim.cli.preview',
        ],
    },
)
