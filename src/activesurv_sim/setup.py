from glob import glob

from setuptools import find_packages, setup

package_name = 'activesurv_sim'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    package_data={package_name: ['py.typed']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/config', glob('config/*.yaml')),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='activesurv developers',
    maintainer_email='dev@activesurv.invalid',
    description=(
        'The simulated world: renderer, simulated cameras and stages, the xy table and its '
        'paths, and the sensor-model experiment.'
    ),
    license='Apache-2.0',
    entry_points={
        'console_scripts': [
            'sim_camera = activesurv_sim.sim_camera_node:main',
            'lab_camera = activesurv_sim.lab_camera_node:main',
            'sim_stage = activesurv_sim.sim_stage_node:main',
            'xy_table = activesurv_sim.xy_table_node:main',
        ],
    },
)
